"""The sample changer (drivers.sample_changer, docs/sample-changer-protocol.md): requests and replies byte for
byte, and the driver against the virtual lab's changer (drivers.virtual.changer_emulator) over a real socket:
what it places, an original shown as the stand-in its magazine slot holds, a refusal as one line."""
from __future__ import annotations

import pytest

from dualrgb.drivers import sample_changer as sc
from dualrgb.drivers.virtual.changer_emulator import ChangerEmulator


def test_requests_and_replies_byte_for_byte():
    assert sc.request_line("PLACE", 0, "test") == b"PLACE 0 test\n"
    assert sc.request_line("PLACE", 1, sc.encode("original:ACC 12+")) == b"PLACE 1 original:ACC%2012%2B\n"
    assert sc.encode("original:東博-F-7") == "original:%E6%9D%B1%E5%8D%9A-F-7"
    assert sc.decode("original:%E6%9D%B1%E5%8D%9A-F-7") == "original:東博-F-7"
    assert sc.request_line("LOAD", "shadow", "ACC-1") == b"LOAD shadow ACC-1\n"
    assert sc.parse_reply("PLACE", b"OK PLACE 0 original:ACC%2012\n") == ["0", "original:ACC%2012"]
    assert sc.parse_reply("IDN?", b"OK IDN DRGB-CHANGER-EMU 1.0.0 EMU-0001\n") == ["DRGB-CHANGER-EMU",
                                                                                    "1.0.0 EMU-0001"]
    with pytest.raises(sc.ChangerError, match="^sample changer: the tray is empty$"):
        sc.parse_reply("PLACE", b"ERR 3 the tray is empty\n")
    with pytest.raises(sc.ChangerError, match="unexpected reply 'OK LOAD x y' to PLACE"):
        sc.parse_reply("PLACE", b"OK LOAD x y\n")
    with pytest.raises(ValueError, match="unknown sample changer command 'EJECT'"):
        sc.request_line("EJECT")


@pytest.mark.parametrize("what", ["", "original:", "table", "original:a\tb", "original:" + "x" * 600])
@pytest.mark.fault("input")
def test_what_cannot_be_placed_is_refused_before_it_is_sent(what):
    with pytest.raises(ValueError, match="cannot place"):
        sc.check_thing(what)


@pytest.fixture
def changer():
    placed: list[tuple[str, bool]] = []
    emulator = ChangerEmulator(lambda what, nd: placed.append((what, nd)), "painting", transport="socket")
    port = emulator.start()
    with sc.SampleChanger(port, timeout=5) as client:
        yield client, emulator, placed
    emulator.stop()


def test_the_changer_places_what_it_is_asked_for_once(changer):
    client, _, placed = changer
    assert client.identify() == {"model": "DRGB-CHANGER-EMU", "version": "1.0.0", "serial": "EMU-0001"}
    assert client.placed() is None
    client.place("test")
    client.place("test")                        # already there: not moved again
    client.place("train", nd=True)
    assert placed == [("test", False), ("train", True)] and client.placed() == ("train", True)


@pytest.mark.parametrize("slot, expected", [
    ("", ("original:painting", False)),          # nothing loaded: the lab's default stand-in
    ("shadow", ("original:shadow", False)),
    ("test", ("test", False)),
    ("test+nd", ("test", True)),
])
def test_an_original_is_shown_as_what_its_magazine_slot_holds(changer, slot, expected):
    client, _, placed = changer
    if slot:
        client.load("ACC 1", slot)
    client.place("original:ACC 1")
    assert placed == [expected] and client.placed() == ("original:ACC 1", False)


def test_an_identifier_in_any_script_with_spaces(changer):
    client, _, placed = changer
    client.load("東博 F-7", "shadow")
    assert client.place("original:東博 F-7") == "original:東博 F-7"
    assert placed == [("original:shadow", False)] and client.placed() == ("original:東博 F-7", False)


def test_a_slot_for_any_original(changer):
    client, _, placed = changer
    client.load(sc.ANY_ORIGINAL, "film")
    client.load("ACC-2", "shadow")
    client.place("original:ACC-1")
    client.place("original:ACC-2")
    assert placed == [("original:film", False), ("original:shadow", False)]


@pytest.mark.fault("device errors")
def test_what_the_lab_cannot_show_is_one_line_and_nothing_is_placed(changer):
    client, emulator, _ = changer
    emulator._place = lambda what, nd: (_ for _ in ()).throw(ValueError(f"cannot place {what!r}: no such"))
    client.load("X-1", "unicorn")
    with pytest.raises(sc.ChangerError, match="^sample changer: cannot place 'original:unicorn': no such$"):
        client.place("original:X-1")
    assert client.placed() is None
    with pytest.raises(sc.ChangerError, match="holds the charts it was loaded with"):
        client.request("CHART", "train", "-", "-", "-")
