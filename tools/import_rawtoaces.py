"""Convert camera spectral sensitivities of the rawtoaces data set to the project's spectral CSV.

    python -m tools.import_rawtoaces nikon_d700_380_780_5.json sony_ilce-7rm2_380_780_5.json \
        --commit <rawtoaces commit> --out resources/cameras

The rawtoaces repository (AcademySoftwareFoundation/rawtoaces, Apache-2.0, ``data/camera/*.json``) publishes
measured relative sensitivities of real camera bodies, 380-780 nm by 5 nm, as JSON (``spectral_data.data.main``:
wavelength -> [R, G, B]). The conversion keeps every number as published (no resampling, no renormalisation),
renames the channels red, green, blue and writes the provenance header (source, commit, licence, conversion);
the licence text travels beside the CSVs (resources/cameras/LICENSE-rawtoaces), as Apache-2.0 section 4 asks.
"""
from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

import numpy as np

from dualrgb.simulation.spectral_io import write_spectral_csv

log = logging.getLogger(__name__)

REPOSITORY = "https://github.com/AcademySoftwareFoundation/rawtoaces"
LICENCE = ("Apache-2.0, Copyright Contributors to the rawtoaces Project; licence text in "
           "resources/cameras/LICENSE-rawtoaces")


def convert(source: Path, out_dir: Path, commit: str) -> Path:
    """Write ``<out_dir>/<manufacturer>_<model>_rawtoaces.csv`` from one rawtoaces camera JSON."""
    doc = json.loads(source.read_text())
    header, spectral = doc["header"], doc["spectral_data"]
    if spectral["index"]["main"] != ["R", "G", "B"]:
        raise ValueError(f"{source}: channels {spectral['index']['main']}, expected R, G, B")
    rows = sorted((float(wl), values) for wl, values in spectral["data"]["main"].items())
    wl = np.array([w for w, _ in rows])
    values = np.array([v for _, v in rows], dtype=float)
    name = f"{header['manufacturer']}_{header['model']}".lower().replace("-", "_")
    out = out_dir / f"{name}_rawtoaces.csv"
    write_spectral_csv(out, wl, values, ["red", "green", "blue"], {
        "title": f"Camera spectral sensitivity, {header['manufacturer'].title()} {header['model'].upper()} "
                 "(measured)",
        "units": f"relative sensitivity ({spectral['units']}, as published)",
        "source": f"{REPOSITORY} data/camera/{source.name} at commit {commit} "
                  f"(document {header['unique_identifier']}, {header['laboratory']}, "
                  f"{header['document_creation_date']})",
        "licence": LICENCE,
        "conversion": "spectral_data.data.main rows unchanged (wavelength nm -> R, G, B as red, green, blue); "
                      "no resampling or renormalisation",
        "generated_by": "tools/import_rawtoaces.py (python -m tools.import_rawtoaces)",
    }, fmt="%.10g")
    log.info("wrote %s (%d wavelengths)", out, len(wl))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("json", type=Path, nargs="+", help="rawtoaces data/camera/*.json files")
    p.add_argument("--commit", required=True, help="the rawtoaces commit the files were read at")
    p.add_argument("--out", type=Path, default=Path(__file__).parent / "cameras")
    args = p.parse_args()
    for source in args.json:
        print(convert(source, args.out, args.commit))


if __name__ == "__main__":
    main()
