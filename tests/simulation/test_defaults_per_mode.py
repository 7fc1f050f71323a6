"""dualrgb.simulation.defaults: one entry per target mode (format 2), old single-mode files still read, every reader
asks for its mode."""
import json

import pytest

from dualrgb.simulation.defaults import FALLBACK_DEFAULTS, FORMAT, FORMAT_V1, default_grid, load_defaults, save_defaults


def _v2(tmp_path, **modes):
    p = tmp_path / "parsimony.json"
    p.write_text(json.dumps({"format": FORMAT, "modes": modes}))
    return p


def test_each_mode_reads_its_own_entry(tmp_path):
    p = _v2(tmp_path, reflective={"spectral_step_nm": 10.0, "hdr_merge": "variance"},
            transmissive={"spectral_step_nm": 5.0, "spectral_start_nm": 380.0, "hdr_merge": "thesis"})
    r, t = load_defaults("reflective", p), load_defaults("transmissive", p)
    assert (r["spectral_step_nm"], r["spectral_start_nm"], r["hdr_merge"]) == (10.0, 410.0, "variance")
    assert (t["spectral_step_nm"], t["spectral_start_nm"], t["hdr_merge"]) == (5.0, 380.0, "thesis")
    assert default_grid("transmissive", p).label() == "380-780 nm / 5 nm"
    assert set(r) == set(FALLBACK_DEFAULTS)


def test_a_single_mode_file_holds_for_both_modes_and_junk_falls_back(tmp_path, caplog):
    p = tmp_path / "old.json"
    p.write_text(json.dumps({"format": FORMAT_V1, "spectral_step_nm": 20.0, "hdr_exposures": 3}))
    for mode in ("reflective", "transmissive"):
        assert load_defaults(mode, p)["spectral_step_nm"] == 20.0 and load_defaults(mode, p)["hdr_exposures"] == 3
    p.write_text(json.dumps({"format": "dualrgb-parsimony/9", "spectral_step_nm": 20.0}))
    assert load_defaults("reflective", p) == FALLBACK_DEFAULTS
    assert "format" in caplog.text
    q = _v2(tmp_path, reflective={"spectral_step_nm": 5.0})
    assert load_defaults("transmissive", q) == FALLBACK_DEFAULTS          # no entry for the mode: the thesis'


def test_unknown_mode_is_refused_in_one_line(tmp_path):
    with pytest.raises(ValueError, match="mode 'film'"):
        load_defaults("film")


def test_save_updates_one_mode_and_keeps_the_rest(tmp_path):
    p = tmp_path / "d.json"
    p.write_text(json.dumps({"format": FORMAT_V1, "spectral_step_nm": 20.0, "hdr_merge": "variance",
                             "evidence": {"old": 1}}))
    save_defaults(p, "transmissive", {"spectral_step_nm": 5.0, "evidence": {"grid": 2}},
                  header={"generated_by": "test"})
    d = json.loads(p.read_text())
    assert d["format"] == FORMAT and d["generated_by"] == "test"
    assert d["modes"]["transmissive"]["spectral_step_nm"] == 5.0
    assert d["modes"]["transmissive"]["evidence"] == {"old": 1, "grid": 2}
    assert d["modes"]["reflective"]["spectral_step_nm"] == 20.0 and d["modes"]["reflective"]["hdr_merge"] == "variance"
    save_defaults(p, "reflective", {"hdr_merge": "thesis"})
    assert load_defaults("reflective", p)["hdr_merge"] == "thesis"
    assert load_defaults("transmissive", p)["hdr_merge"] == "variance"


def test_the_hdr_merge_default_follows_the_mode(tmp_path, monkeypatch):
    import dualrgb.simulation.defaults as defaults
    from dualrgb.simulation.hdr_estimators import default_method

    p = _v2(tmp_path, reflective={"hdr_merge": "variance"}, transmissive={"hdr_merge": "thesis"})
    monkeypatch.setattr(defaults.resources, "user_or_packaged", lambda *parts: p)
    assert default_method("reflective") == "variance" and default_method("transmissive") == "thesis"
    with pytest.raises(ValueError, match="differs by mode"):           # a merge that does not know its mode
        default_method(None)
    p.write_text(json.dumps({"format": FORMAT, "modes": {m: {"hdr_merge": "variance"} for m in
                                                         ("reflective", "transmissive")}}))
    assert default_method(None) == "variance"
