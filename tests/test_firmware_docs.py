"""The reference firmware's documents stay true (issue 38): its command table is generated from the protocol's one
table, the wiring and the fuses in firmware/README.md are the code's, the protocol page's "Reference firmware"
section names the identity the firmware answers and cites a passing run of make firmware-check
(docs/data/firmware-check.json). Without the AVR toolchain only the image test skips."""
from __future__ import annotations

import importlib.util
import json
import re
import subprocess
from pathlib import Path

import pytest
import sphere_firmware as fw
from sphere_backends import FIRMWARE_MISSING, FirmwareBackend

from dualrgb.drivers.led_sphere import protocol as P

ROOT = Path(__file__).resolve().parents[1]
FIRMWARE = ROOT / "firmware"
README = FIRMWARE / "README.md"
PAGE = ROOT / "docs" / "led-sphere-protocol.md"
CHECK = ROOT / "docs" / "data" / "firmware-check.json"


def _generator():
    spec = importlib.util.spec_from_file_location("gen_protocol_table", FIRMWARE / "gen_protocol_table.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _readme_table(heading: str) -> list[list[str]]:
    """The rows of the first Markdown table after the line starting with ``heading``."""
    text = README.read_text(encoding="utf-8")
    lines = text[text.index(heading):].splitlines()
    rows, started = [], False
    for line in lines[1:]:
        if line.strip().startswith("|"):
            started = True
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if not set("".join(cells)) <= set("- "):
                rows.append(cells)
        elif started:
            break
    return rows[1:]                         # without the header row


def test_the_command_table_is_generated_from_the_protocol():
    assert _generator().main(["--check"]) == 0
    header = (FIRMWARE / "src" / "protocol_table.h").read_text(encoding="ascii")
    for cmd in P.TABLE:
        assert f'"{cmd.keyword}"' in header and f'"{cmd.keyword} takes {cmd.arg_format() or "no arguments"}"' in header
    assert f'#define PROTO_FIRMWARE_VERSION "{P.FIRMWARE_VERSION}"' in header


def test_the_wiring_in_the_readme_is_the_firmwares_and_the_harness():
    outputs = (FIRMWARE / "src" / "outputs.c").read_text(encoding="ascii")
    code = re.findall(r"&OCR(\d)([ABC]), &PORT([A-L]), &DDR\3, _BV\(COM\1\2\d\), _BV\(P\3(\d)\), \d\},\s+"
                      r"/\* LED (\d+)\s+(D\d+) \*/", outputs)
    assert len(code) == fw.N_LEDS
    from_code = [[led, f"OC{t}{c}", f"P{port}{bit}", pin] for t, c, port, bit, led, pin in code]
    readme = [[r[0], r[2], r[3], r[4]] for r in _readme_table("PWM outputs (16-bit timers")]
    assert readme == from_code
    harness = (FIRMWARE / "sim" / "harness.c").read_text(encoding="ascii")
    pwm_pins = re.search(r"PWM_PINS\[N_LEDS\] = \{(.*?)\};", harness, re.S)
    assert pwm_pins is not None
    assert [f"P{p}{b}" for p, b in re.findall(r"\{'([A-L])', (\d)\}", pwm_pins.group(1))] == [r[2] for r in readme]


def test_the_sensor_pins_in_the_readme_are_the_firmwares_and_the_harness():
    inputs = (FIRMWARE / "src" / "inputs.c").read_text(encoding="ascii")
    harness = (FIRMWARE / "sim" / "harness.c").read_text(encoding="ascii")
    readme = {row[0]: row[1:4] for row in _readme_table("Sensors (inputs)")}
    for name, array in (("current sense", "SENSE"), ("driver fault flag", "FAULT")):
        block = re.search(array + r"\[N_LEDS\] = \{(.*?)\};", inputs, re.S)
        sim_block = re.search(array + r"_PINS\[N_LEDS\] = \{(.*?)\};", harness, re.S)
        assert block is not None and sim_block is not None
        pins = [f"P{p}{b}" for p, b in re.findall(r"\{&PIN([A-L]), _BV\(P[A-L](\d)\)\}", block.group(1))]
        assert pins == [f"P{p}{b}" for p, b in re.findall(r"\{'([A-L])', (\d)\}", sim_block.group(1))]
        first = readme[name][0].split()[0]                     # PA0-PA7 / PK0-PK7
        port = first[1]
        assert first == f"P{port}0-P{port}7" and pins[:8] == [f"P{port}{i}" for i in range(8)]
        assert [readme[name][1].split()[0], readme[name][2].split()[0]] == pins[8:]


def test_the_fuses_are_the_same_in_the_code_the_makefile_and_the_readme():
    main = (FIRMWARE / "src" / "main.c").read_text(encoding="ascii")
    fuses = dict(re.findall(r"\.(low|high|extended) = (0x[0-9A-F]{2})", main))
    assert set(fuses) == {"low", "high", "extended"}
    makefile = (FIRMWARE / "Makefile").read_text(encoding="ascii")
    assert f"-U lfuse:w:{fuses['low']}:m -U hfuse:w:{fuses['high']}:m -U efuse:w:{fuses['extended']}:m" in makefile
    readme = {row[0]: row[1].strip("`") for row in _readme_table("* **Through an ISP programmer")}
    assert readme == fuses


def test_the_protocol_page_says_what_the_firmware_answers_and_cites_a_passing_check():
    page = PAGE.read_text(encoding="utf-8")
    section = page[page.index("## Reference firmware"):]
    board = (FIRMWARE / "src" / "board.h").read_text(encoding="ascii")
    model = re.search(r'#define SPHERE_MODEL "(\S+)"', board)
    serial = re.search(r'#define SPHERE_SERIAL "(\S+)"', board)
    assert model and serial and (model.group(1), serial.group(1)) == (FirmwareBackend.model, FirmwareBackend.serial)
    assert f"`OK IDN {model.group(1)} {P.FIRMWARE_VERSION} {serial.group(1)}`" in section
    cited = set(re.findall(r"\{json\}`data/firmware-check\.json#(\w+)", section))
    check = json.loads(CHECK.read_text(encoding="utf-8"))
    assert cited <= set(check) and {"passed", "cases", "on_limit_off_s", "host_loss_off_s", "cap_s"} <= cited
    assert set(check) == {"mcu", "cases", "passed", "failed", "host_loss_off_s", "on_limit_off_s", "cap_s"}
    assert check["mcu"] == "atmega2560" and check["failed"] == 0 and check["passed"] == check["cases"] > 0
    assert 0 < check["on_limit_off_s"] <= check["cap_s"] and 0 < check["host_loss_off_s"] <= check["cap_s"]


@pytest.mark.skipif(FIRMWARE_MISSING is not None, reason=str(FIRMWARE_MISSING))
def test_the_image_carries_its_fuses_and_fits():
    """(Not a case on the simulated chip: it runs with the rest of the suite, where avr-gcc is installed.)"""
    fw.build()
    dump = subprocess.run(["avr-objdump", "-s", "-j", ".fuse", str(fw.ELF)], capture_output=True, text=True,
                          check=True).stdout
    row = re.search(r"^ 820000 ([0-9a-f]{6})", dump, re.M)
    assert row is not None and row.group(1) == "ffc1fd"           # low, high, extended
    size = subprocess.run(["avr-size", "-A", str(fw.ELF)], capture_output=True, text=True, check=True).stdout
    sections = {m.group(1): int(m.group(2)) for m in re.finditer(r"^\.(\w+)\s+(\d+)", size, re.M)}
    assert sections["text"] + sections.get("data", 0) < 256 * 1024 - 8 * 1024    # flash, boot section left free
    assert sections.get("data", 0) + sections.get("bss", 0) < 6 * 1024           # of 8 KiB RAM: room for stack
