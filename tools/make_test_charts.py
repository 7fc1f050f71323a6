"""Write the chart reference files the tests calibrate with (maintainer script, not shipped; run it again only to
change them: ``python -m tools.make_test_charts``). Both are spectral CGATS as the field writes them, made from
data colour-science ships (tests/data/charts/README.md says where each spectrum comes from and its licence):

* ``tests/data/charts/sg140_layout.txt``: a 140-patch chart in the ColorChecker Digital SG's layout (10 rows x 14
  columns, columns lettered A-N, rows 1-10), written as X-Rite's software writes an SG reference: tab-separated,
  ``SampleID`` and ``SAMPLE_NAME`` (A1, A2 ... N10, column by column), fields ``nm380`` ... ``nm730`` (10 nm: the
  range vendors measure, 50 nm short of the 780 nm the grids reach), and a ``NUMBER_OF_FIELDS`` that disagrees
  with the data format (as real vendor files do). The border (rows 1 and 10, columns A and N: 44 patches) repeats
  three neutrals, as the SG's border does; inside, the 24 ISO 17321-1 ColorChecker spectra and 72 of the rawtoaces
  training reflectances.
* ``tests/data/charts/cc24_test.cie``: a 24-patch ColorChecker Classic test reference (Ohta's measurement, 380-780
  nm by 5 nm) written as ArgyllCMS writes spectral files: ``SPECTRAL_START_NM`` / ``SPECTRAL_END_NM`` /
  ``SPECTRAL_BANDS``, fields ``SPEC_380`` ..., ``SAMPLE_ID`` A1 .. D6 (rows A-D, columns 1-6), DEVICE_CLASS OUTPUT.
* ``tests/data/charts/it872_layout.cie``: a 288-patch reflective chart in the IT8.7/2 layout (rows A-L x columns
  01-22, then the grey scale GS00 .. GS23), ArgyllCMS style like the CC24 file, 380-730 nm by 10 nm: the 190
  rawtoaces training reflectances, the 24 ISO 17321-1 ColorChecker spectra and 50 mixtures of rawtoaces pairs
  (the geometric mean of two reflectances, as two inks overprinted), then 24 near-flat greys from 3 % to 88 %.
"""
from __future__ import annotations

import logging
from pathlib import Path

import colour
import numpy as np

from dualrgb.simulation.cgats import write_cgats_spectra

log = logging.getLogger(__name__)

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "tests" / "data" / "charts"
SG_ROWS, SG_COLS = 10, 14
BORDER_NEUTRALS = ("white 9.5 (.05 D)", "black 2 (1.5 D)", "neutral 5 (.70 D)")


def _iso_spectra(wavelengths: np.ndarray) -> dict[str, np.ndarray]:
    return {name: sd.copy().align(colour.SpectralShape(float(wavelengths[0]), float(wavelengths[-1]),
                                                       float(wavelengths[1] - wavelengths[0]))).values
            for name, sd in colour.SDS_COLOURCHECKERS["ISO 17321-1"].items()}


def sg_layout_spectra(wavelengths: np.ndarray) -> tuple[list[str], np.ndarray]:
    """(names A1 .. N10 column by column, spectra (140, n_wl)) of the SG-layout chart (module docstring)."""
    iso = _iso_spectra(wavelengths)
    training = colour.characterisation.read_training_data_rawtoaces_v1()
    rawtoaces = np.asarray(training.copy().align(colour.SpectralShape(
        float(wavelengths[0]), float(wavelengths[-1]), float(wavelengths[1] - wavelengths[0]))).values).T
    inner = [iso[n] for n in list(iso)[:24]] + [rawtoaces[i] for i in np.linspace(0, 189, 72).round().astype(int)]
    names, spectra, k = [], [], 0
    for col in range(SG_COLS):
        for row in range(SG_ROWS):
            names.append(f"{chr(ord('A') + col)}{row + 1}")
            if row in (0, SG_ROWS - 1) or col in (0, SG_COLS - 1):
                spectra.append(iso[BORDER_NEUTRALS[(row + col) % 3]])
            else:
                spectra.append(inner[k])
                k += 1
    return names, np.clip(np.asarray(spectra), 0.0, None)


def write_sg(path: Path) -> Path:
    wl = np.arange(380.0, 731.0, 10.0)
    names, spectra = sg_layout_spectra(wl)
    fields = ["SampleID", "SAMPLE_NAME", *(f"nm{w:g}" for w in wl)]
    lines = ["LGOROWLENGTH\t10", 'CREATED\t"11/27/2026"', 'INSTRUMENTATION\t"i1Pro 2"',
             'MEASUREMENT_SOURCE\t"Illumination=D50\tObserverAngle=2°\tWhiteBase=Abs\tFilter=No"',
             'DESCRIPTOR\t"ColorChecker Digital SG layout, test chart (tools/make_test_charts.py)"',
             'KEYWORD\t"SampleID"', 'KEYWORD\t"SAMPLE_NAME"',
             f"NUMBER_OF_FIELDS\t{len(fields) + 2}",               # disagrees with the format, as vendor files do
             "BEGIN_DATA_FORMAT", "\t".join(fields), "END_DATA_FORMAT", f"NUMBER_OF_SETS\t{len(names)}", "BEGIN_DATA"]
    lines += ["\t".join([str(i + 1), name, *(f"{v:.4f}" for v in spectrum)])
              for i, (name, spectrum) in enumerate(zip(names, spectra, strict=True))]
    lines.append("END_DATA")
    path.write_text("\r\n".join(lines) + "\r\n", encoding="latin-1")      # X-Rite writes Latin-1 and CRLF
    return path


def write_cc24(path: Path) -> Path:
    wl = np.arange(380.0, 781.0, 5.0)
    ohta = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]
    values = np.stack([sd.copy().align(colour.SpectralShape(380, 780, 5)).values for sd in ohta.values()], axis=1)
    names = [f"{chr(ord('A') + i // 6)}{i % 6 + 1}" for i in range(24)]
    return write_cgats_spectra(path, wl, values, names, file_id="CTI3", device_class="OUTPUT", fmt="%.4f",
                               descriptor="ColorChecker Classic, Ohta (1997), test chart (tools/make_test_charts.py)")


def it872_spectra(wavelengths: np.ndarray) -> tuple[list[str], np.ndarray]:
    """(names A01 .. L22 row by row then GS00 .. GS23, spectra (288, n_wl)) of the IT8.7/2-layout chart."""
    shape = colour.SpectralShape(float(wavelengths[0]), float(wavelengths[-1]), float(wavelengths[1] - wavelengths[0]))
    iso = _iso_spectra(wavelengths)
    raw = np.asarray(colour.characterisation.read_training_data_rawtoaces_v1().copy().align(shape).values).T
    raw = np.clip(raw, 1e-3, None)
    rng = np.random.default_rng(872)
    pairs = rng.choice(len(raw), size=(50, 2), replace=False if len(raw) >= 100 else True)
    mixes = [np.sqrt(raw[a] * raw[b]) for a, b in pairs]
    colours = [*raw, *(iso[n] for n in list(iso)[:24]), *mixes]
    tilt = 1.0 + 0.03 * (wavelengths - wavelengths.mean()) / np.ptp(wavelengths)        # greys are never flat
    greys = [g * tilt for g in np.geomspace(0.88, 0.03, 24)]
    names = [f"{chr(ord('A') + r)}{c + 1:02d}" for r in range(12) for c in range(22)]
    names += [f"GS{k:02d}" for k in range(24)]
    return names, np.clip(np.asarray([*colours, *greys]), 0.0, None)


def write_it872(path: Path) -> Path:
    wl = np.arange(380.0, 731.0, 10.0)
    names, spectra = it872_spectra(wl)
    return write_cgats_spectra(path, wl, spectra.T, names, file_id="CTI3", device_class="OUTPUT", fmt="%.4f",
                               descriptor="IT8.7/2 layout, reflective test chart (tools/make_test_charts.py)")


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for path in (write_sg(OUT / "sg140_layout.txt"), write_cc24(OUT / "cc24_test.cie"),
                 write_it872(OUT / "it872_layout.cie")):
        print(f"wrote {path.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
