"""``dualrgb cube``: the spectral cube (and its rendering under a chosen light) of a delivery, made from the
delivered camera-RGB TIFFs through the map its sidecar states (app.processing.cube_map).

A full-resolution delivery states its cube instead of writing it (app.workflow.delivery.deliverables says why); this
writes it, streamed in row bands, memory bounded by the band: ``<stem>_spectral.img`` / ``.hdr`` (ENVI, BIL,
16-bit x 10000, as a half-resolution delivery's) and with ``render`` ``<stem>_under_<light>_prophoto_16bit.tif``.
Nothing unverified is used: the sidecar is read as JSON and checked against its schema, and the channel files
against the sidecar's size and SHA-256, first (an edited sidecar or a changed byte stops it in one line, naming the
file). By default into the delivery's folder, and then the files it made are
added to the sidecar's ``files`` and ``fixity`` (``dualrgb verify`` checks them, ``dualrgb bag`` packs them); a
delivery whose cube is a delivered file is not written over (another ``out`` folder is needed, and a cube made
there is not part of the delivery).
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from dualrgb.app.processing.cube_map import estimator_of_map, materialise
from dualrgb.app.processing.envi import EnviHeader
from dualrgb.common.progress import CancelToken, ProgressCallback, scaled

log = logging.getLogger(__name__)


@dataclass
class OnDemand:
    """What :func:`make_cube` wrote."""

    cube: Path
    header: Path
    render: Path | None
    shape: tuple[int, int]


def _lux_s(doc: dict) -> float | None:
    """The sidecar's dose in lux.s, None where it was not recorded (an imported session's)."""
    value = (doc.get("light_dose") or {}).get("lux_s")
    return None if value is None else float(value)


def _sidecar_of(delivery: Path) -> Path:
    delivery = Path(delivery)
    if delivery.is_file():
        return delivery
    found = delivery / f"{delivery.name}.json"
    if not found.is_file():
        raise ValueError(f"{delivery}: no sidecar {found.name} (expected a delivery's folder or its sidecar)")
    return found


def make_cube(delivery: Path, out: Path | None = None, render: str | None = None, *, band_rows: int = 64,
              progress: ProgressCallback | None = None, cancel: CancelToken | None = None) -> OnDemand:
    """Write the cube of ``delivery`` (its folder or sidecar) into ``out`` (default the delivery's folder), and
    with ``render`` (a light's command-line name) its rendering under that light."""
    from dualrgb.app.processing.render import check_illuminant
    from dualrgb.app.workflow.delivery.deliverables import render_name

    sidecar = _sidecar_of(delivery)
    doc = checked_sidecar(sidecar)
    sp = doc.get("spectral")
    if not sp or "map" not in sp:
        raise ValueError(f"{sidecar}: this delivery has no spectral map (its calibration had no spectral estimator, "
                         "or it was delivered before the map was stated)")
    light = check_illuminant(render) if render else None
    folder = sidecar.parent
    out = Path(out) if out is not None else folder
    if sp["cube"].get("delivery") != "on-demand" and out.resolve() == folder.resolve():
        raise ValueError(f"{folder}: its cube is a delivered file; give another folder (--out) for a new one")
    stem = str(doc["file_stem"])
    est = estimator_of_map(sp["map"])
    channels = [folder / name for name in sp["map"]["channel_files"]]
    check_inputs(sidecar, doc, channels)
    out.mkdir(parents=True, exist_ok=True)
    data = out / f"{stem}_spectral.img"
    lines, samples = materialise(channels, est, data, band_rows=band_rows, cancel=cancel,
                                 progress=scaled(progress, 0.0, 0.7 if light else 1.0))
    header = out / f"{stem}_spectral.hdr"
    _header(doc, est, lines, samples).write(header)
    rendered = None
    if light is not None:
        rendered = out / render_name(stem, light)
        _render(doc, channels, est, light, rendered, band_rows, scaled(progress, 0.7, 1.0), cancel)
    if out.resolve() == folder.resolve():
        record(sidecar, doc, {"spectral": data, "spectral_header": header,
                              **({f"render_{light}": rendered} if rendered is not None else {})})
    log.info("cube of %s made on demand: %s", doc["original"]["identifier"], data)
    return OnDemand(data, header, rendered, (lines, samples))


def checked_sidecar(sidecar: Path) -> dict:
    """The sidecar's JSON, refused in one line naming it when it is not JSON or does not follow the delivery schema
    (app.workflow.delivery.fixity.schema_problems, as ``dualrgb verify`` reads it): an edited map is never used."""
    from dualrgb.app.workflow.delivery.delivery_folder import read_sidecar
    from dualrgb.app.workflow.delivery.fixity import schema_problems

    try:
        doc = read_sidecar(sidecar)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"not made: {sidecar}: not UTF-8 JSON ({exc}); the sidecar is damaged") from None
    problems = schema_problems(doc)
    if problems:
        raise ValueError(f"not made: {sidecar}: {problems[0]} (the sidecar was edited or damaged; dualrgb verify "
                         f"{sidecar.parent} lists every problem)")
    return doc


def check_inputs(sidecar: Path, doc: dict, files: list[Path]) -> None:
    """Nothing unverified is used: each input file against the size and SHA-256 its sidecar recorded (one line
    naming the first that differs, the cube not made)."""
    from dualrgb.app.workflow.delivery.fixity import FIXITY_ALGORITHM, VerifyReport, check_file

    listed = ((doc.get("fixity") or {}).get("files") or {}) if doc.get("fixity", {}).get("algorithm") == \
        FIXITY_ALGORITHM else {}
    report = VerifyReport()
    for path in files:
        if path.name not in listed:
            report.problems.append(f"{path}: not in the fixity of {sidecar.name}: it cannot be checked")
            continue
        check_file(path, listed[path.name], report)
    if report.problems:
        raise ValueError(f"not made: {report.problems[0]} (dualrgb verify {sidecar.parent} lists every problem)")


def record(sidecar: Path, doc: dict, made: dict[str, Path]) -> None:
    """The files made for the delivery into its sidecar: listed in ``files`` and in ``fixity`` (so ``dualrgb
    verify`` checks them and ``dualrgb bag`` packs them), the cube marked as made; written atomically."""
    from dualrgb.app.workflow.delivery.delivery import write_sidecar
    from dualrgb.app.workflow.delivery.fixity import file_fixity, fixity_section

    doc["files"] = {**doc.get("files", {}), **{k: p.name for k, p in made.items()}}
    listed = dict((doc.get("fixity") or {}).get("files") or {})
    listed.update({p.name: file_fixity(p) for p in made.values()})
    doc["fixity"] = fixity_section(listed)
    doc["spectral"]["cube"]["made_on_demand"] = {"data": made["spectral"].name, "header": made["spectral_header"].name,
                                                 "made_at": datetime.now(UTC).isoformat(timespec="seconds")}
    write_sidecar(sidecar, doc)


def _header(doc: dict, est, lines: int, samples: int) -> EnviHeader:
    """The ENVI header of the cube made on demand: the delivered cube's, in ASCII (ENVI headers are), saying so."""
    from dualrgb.core.metadata import ascii_text
    from dualrgb.simulation.versions import dualrgb_version

    original = doc["original"]
    ident, title = str(original["identifier"]), str(original.get("title") or "")
    cal = str((doc.get("calibration") or {}).get("id", ""))
    text = (f"dualrgb spectral cube of {ident}" + (f" - {title}" if title else "") + f"; {est.quantity} estimated by "
            f"{est.method} from {est.n_channels} channels; calibration {cal}; made on demand from the camera-RGB files")
    return EnviHeader(lines, samples, est.n_wavelengths, [float(w) for w in est.wavelengths], ascii_text(text),
                      extra={"dualrgb identifier": ascii_text(ident), "dualrgb calibration": cal,
                             "dualrgb method": est.method, "dualrgb quantity": est.quantity,
                             "dualrgb software": f"dualrgb {dualrgb_version()}"})


def _render(doc: dict, channels: list[Path], est, light: str, path: Path, band_rows: int,
            progress: ProgressCallback | None, cancel: CancelToken | None) -> None:
    """The rendering under ``light`` from the channel files, tagged like the delivery's other TIFFs."""
    from dualrgb.app.processing.cube_map import channels_band, open_channels
    from dualrgb.app.processing.render import rendering
    from dualrgb.app.processing.spectral_cube import SpectralEncoder
    from dualrgb.app.workflow.delivery.deliverables import spectral_files
    from dualrgb.app.workflow.delivery.delivery import open_deliverable
    from dualrgb.common.progress import check, report

    r = rendering(light, est.wavelengths)
    im = spectral_files(path.parent, str(doc["file_stem"]), est, r)["render"]
    arrays = open_channels(channels)
    H, W, _ = arrays[0].shape
    band = None
    with SpectralEncoder((H, W, est.n_channels), est.matrix, est.bounds, r, offset=est.offset) as enc, \
            open_deliverable(im, H, W, context_of(doc), band_rows, None, True) as out:
        for r0 in range(0, H, out.band_rows):
            check(cancel)
            r1 = min(r0 + out.band_rows, H)
            band = channels_band(arrays, r0, r1, band)
            enc.encode(r0, None, out.band(r1 - r0), band=band)
            out.commit()
            report(progress, r1 / H, f"rendering rows {r1} of {H}")


def context_of(doc: dict):
    """What a delivery's files say about it (app.workflow.delivery.master_metadata.MasterContext), from its sidecar:
    for a
    file made later for the same delivery."""
    from dualrgb.app.workflow.calibration.profile import CameraIdentity
    from dualrgb.app.workflow.delivery.delivery_settings import load
    from dualrgb.app.workflow.delivery.master_metadata import MasterContext
    from dualrgb.core.metadata import Original

    now = datetime.now(UTC)
    captured = datetime.fromisoformat(str(doc.get("captured_at") or doc.get("created_at") or now.isoformat()))
    exposures = {str(k): [float(t) for t in v] for k, v in (doc.get("exposures") or {}).items()}
    cal = doc.get("calibration") or {}
    return MasterContext(Original.from_dict(doc["original"]), str(cal.get("id", "")), CameraIdentity(**doc["camera"]),
                         _lux_s(doc), doc.get("ppi"), now, captured, exposures, list(exposures),
                         load(), f"made on demand from the camera-RGB files (calibration {cal.get('id', '')})")
