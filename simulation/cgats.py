"""Spectra from CGATS / X-Rite measurement files (ANSI CGATS.17, i1Profiler, ArgyllCMS .ti3 / .sp, X-Rite
ColorChecker data) as a :class:`SpectralTable`: reference targets' reflectances (:func:`read_cgats_spectra`) and
spectroradiometer readings of light sources (:func:`read_cgats_emission`), and the one writer of spectral CGATS
files (:func:`write_cgats_spectra`, the ArgyllCMS spectral keywords).

Why hand-written: colour-science's ``read_sds_from_xrite_file`` reads the X-Rite flavour only ("nm380" fields)
and, by its own description, is "absolutely not bullet-proof": a truncated row or a stray token gives a wrong
spectrum or a Python exception, not a message a user can act on. This reader accepts every field spelling
(``nm380``, ``SPECTRAL_NM380`` / ``SPECTRAL_NM_380``, ArgyllCMS's ``SPEC_380``), quoted names with spaces,
comments, and checks the declared NUMBER_OF_SETS; every problem is one line naming file, line and what was
expected (tests check it against colour's reader on colour's own X-Rite test file). A NUMBER_OF_FIELDS that
disagrees with the DATA_FORMAT list is a warning when the data rows match the list (vendors' files carry such
mismatches; ArgyllCMS reads them, using only NUMBER_OF_SETS). Wavelengths come from ``SPECTRAL_START_NM`` /
``SPECTRAL_END_NM`` (and ``SPECTRAL_BANDS``) when the file declares them: field names are rounded (a 3.33 nm
file names ``SPEC_383`` what is 383.33 nm), so the names must only agree within half a step.

Values are divided by the file's ``SPECTRAL_NORM`` keyword when it has one (ArgyllCMS: the stored values are
value x norm). Reflectance (or transmittance) factors: the unit is decided from the whole file, patch by patch: a
file where no value exceeds 2 holds factors (0-1; up to 2 for fluorescent samples); one where most patches reach
above 2 holds percent (ArgyllCMS writes 0-100), said in a warning line (naming any patches that stay below 2 %),
and is divided by 100; a file where as many patches or more stay within 0-2 as reach above it holds values on both
scales (a typed 5.0 among factors would otherwise turn every value into percent) and is refused in one line naming
the row and value. Values down to -0.005 (instrument noise at the ends of the
spectrum) are set to 0, more negative ones are an error. Colorimetric fields (XYZ_*, LAB_*) are kept in
``CgatsTable.rows`` but not used: they are for the instrument's illuminant and observer (often D50), while the
reference XYZ here is computed from the spectra (eq 4.2 or ASTM E308, ``simulation.datasets.target_xyz``).
Emission (spectral radiance or irradiance of a light source, e.g. ``spotread -s`` / instrument software): the
values after ``SPECTRAL_NORM`` as they are, small negatives (instrument noise) kept; the units are the file's
(``DUALRGB_UNITS`` when dualrgb wrote it; ArgyllCMS's emission unit is mW m^-2 sr^-1 nm^-1).

References
----------
ANSI CGATS.17-2009, *Graphic technology - Exchange format for colour and process control data*; ArgyllCMS file
formats (argyllcms.com/doc/File_Formats.html): the ``.sp`` / ``.ti3`` spectral keywords ``SPECTRAL_BANDS``,
``SPECTRAL_START_NM``, ``SPECTRAL_END_NM``, ``SPECTRAL_NORM`` and fields ``SPEC_<nm>``.
"""
from __future__ import annotations

import logging
import re
import shlex
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dualrgb.common.atomic_files import atomic_write
from dualrgb.simulation.spectral_io import MAX_CSV_BYTES, SpectralDataError, SpectralTable

log = logging.getLogger(__name__)
MAX_CGATS_BYTES = MAX_CSV_BYTES    # an instrument export of hundreds of readings is a few MB

_SPECTRAL = re.compile(r"^(?:SPECTRAL_NM_?|SPECTRAL_|SPEC_|NM_?)(\d+(?:\.\d+)?)$", re.IGNORECASE)
_NAME_FIELDS = ("SAMPLE_NAME", "SAMPLE_ID", "SAMPLEID", "SAMPLE_LOC")
NEGATIVE_TOLERANCE = 0.005
FRACTION_MAX = 2.0      # reflectance factors reach up to 2 (fluorescent samples); above that a value is percent
PERCENT_MAX = 200.0


class CgatsError(SpectralDataError):
    """A CGATS / X-Rite file that cannot be used (one line: file, line, problem)."""


@dataclass
class CgatsTable:
    fields: list[str]
    rows: list[list[str]]
    keywords: dict[str, str] = field(default_factory=dict)
    source: str = ""
    row_lines: list[int] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)    # one line each, also logged (file, what, how read)

    def spectral_fields(self) -> list[tuple[int, float]]:
        """(field index, wavelength nm) of the spectral fields, in file order."""
        out = []
        for i, f in enumerate(self.fields):
            m = _SPECTRAL.match(f)
            if m:
                out.append((i, float(m.group(1))))
        return out

    def names(self) -> list[str]:
        upper = [f.upper() for f in self.fields]
        for key in _NAME_FIELDS:
            if key in upper:
                j = upper.index(key)
                return [r[j] for r in self.rows]
        return [str(i + 1) for i in range(len(self.rows))]

    def spectral_values(self) -> tuple[np.ndarray, np.ndarray]:
        """The spectral fields as numbers: wavelengths (n_wl,), values (n_wl, n_rows) divided by SPECTRAL_NORM
        (1 when absent; no unit is assumed: radiance readings use this too); one-line CgatsError for a missing,
        unordered or non-numeric field, or SPECTRAL_BANDS / _START_NM / _END_NM that disagree with the fields."""
        spec = self.spectral_fields()
        if len(spec) < 2:
            raise CgatsError(f"{self.source}: no spectral fields (expected nm380 ... or SPECTRAL_NM380 ...); "
                             f"fields are {', '.join(self.fields[:12])}{' ...' if len(self.fields) > 12 else ''}")
        wl = np.array([w for _, w in spec])
        if np.any(np.diff(wl) <= 0):
            k = int(np.argmax(np.diff(wl) <= 0))
            raise CgatsError(f"{self.source}: spectral fields must increase in wavelength; {wl[k + 1]:g} nm "
                             f"follows {wl[k]:g} nm")
        wl = self._declared_wavelengths(wl)
        values = np.empty((len(wl), len(self.rows)))
        for r, (row, line) in enumerate(zip(self.rows, self.row_lines, strict=True)):
            for c, (i, _wavelength) in enumerate(spec):
                try:
                    values[c, r] = float(row[i])
                except ValueError:
                    raise CgatsError(f"{self.source}:{line}: field {self.fields[i]} {row[i]!r} is not a number"
                                     ) from None
        if not np.isfinite(values).all():
            c, r = np.argwhere(~np.isfinite(values))[0]
            raise CgatsError(f"{self.source}:{self.row_lines[r]}: {wl[c]:g} nm is not a finite number")
        return wl, values / self._norm()

    def _norm(self) -> float:
        text = self.keywords.get("SPECTRAL_NORM")
        try:
            norm = 1.0 if text is None else float(text)
        except ValueError:
            norm = float("nan")
        if not np.isfinite(norm) or norm <= 0:
            raise CgatsError(f"{self.source}: SPECTRAL_NORM {text!r}: expected a positive number")
        return norm

    def _keyword_number(self, key: str) -> float | None:
        if key not in self.keywords:
            return None
        try:
            value = float(self.keywords[key])
        except ValueError:
            value = float("nan")
        if not np.isfinite(value):
            raise CgatsError(f"{self.source}: {key} {self.keywords[key]!r}: expected a number")
        return value

    def _declared_wavelengths(self, named: np.ndarray) -> np.ndarray:
        """The spectral fields' wavelengths: from SPECTRAL_START_NM / SPECTRAL_END_NM (evenly spaced over the
        fields) when both are declared, else the field names; SPECTRAL_BANDS must count the fields, and the names
        must agree with the declared wavelengths within half a step (names are rounded: ``SPEC_383`` for
        383.33 nm)."""
        bands = self._keyword_number("SPECTRAL_BANDS")
        if bands is not None and int(bands) != len(named):
            raise CgatsError(f"{self.source}: SPECTRAL_BANDS {self.keywords['SPECTRAL_BANDS']!r} does not match the "
                             f"{len(named)} spectral fields ({named[0]:g}-{named[-1]:g} nm)")
        start, end = self._keyword_number("SPECTRAL_START_NM"), self._keyword_number("SPECTRAL_END_NM")
        if start is None or end is None:
            declared = named.copy()
            declared[0], declared[-1] = start if start is not None else named[0], end if end is not None else named[-1]
        else:
            declared = np.linspace(start, end, len(named))
        half_step = 0.5 * float(np.min(np.diff(declared)))
        worst = int(np.argmax(np.abs(declared - named)))
        if not half_step > 0 or abs(declared[worst] - named[worst]) > half_step + 1e-6:
            raise CgatsError(f"{self.source}: SPECTRAL_START_NM / SPECTRAL_END_NM ({declared[0]:g}-{declared[-1]:g} "
                             f"nm over {len(named)} bands) put field {self.fields[self.spectral_fields()[worst][0]]} "
                             f"at {declared[worst]:.4g} nm; expected the fields' wavelengths")
        return declared

    def spectral_table(self) -> SpectralTable:
        """The measured reflectances (or transmittances), wavelengths (n_wl,) x patches (n_wl, n_patches)."""
        wl, values = self._factors(*self.spectral_values())
        if values.min() < -NEGATIVE_TOLERANCE:
            c, r = map(int, np.unravel_index(int(np.argmin(values)), values.shape))
            raise CgatsError(f"{self.source}:{self.row_lines[r]}: negative value {values[c, r]:g} at {wl[c]:g} nm")
        np.maximum(values, 0.0, out=values)
        meta = {k.lower(): v for k, v in self.keywords.items()}
        meta.setdefault("title", Path(self.source).stem)
        return SpectralTable(wl, values, self.names(), meta, self.source, list(self.warnings))

    def _factors(self, wl: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Reflectance (transmittance) factors: the file's unit decided from every patch (module docstring), a
        percent file said in a warning line, a file with patches on both scales refused."""
        top = float(values.max())
        if top <= FRACTION_MAX:
            log.info("%s: spectral values up to %.3g, read as factors (0-1)", self.source, top)
            return wl, values
        if top > PERCENT_MAX:
            raise CgatsError(f"{self.source}: spectral values up to {top:g}: neither factors (0-1) nor percent "
                             "(0-100)")
        peaks = values.max(axis=0)
        names = self.names()
        high = [i for i in range(len(peaks)) if peaks[i] > FRACTION_MAX]
        low = [i for i in range(len(peaks)) if peaks[i] <= FRACTION_MAX]
        if len(high) <= len(low):
            c, r = map(int, np.unravel_index(int(np.argmax(values)), values.shape))
            raise CgatsError(f"{self.source}:{self.row_lines[r]}: values on both scales: patch {names[r]} reaches "
                             f"{values[c, r]:g} at {wl[c]:g} nm ({len(high)} patch{'es' if len(high) > 1 else ''} "
                             f"above {FRACTION_MAX:g}, as percent) while {len(low)} of {len(peaks)} stay within "
                             f"0-{FRACTION_MAX:g} (as factors); give every value in one unit (0-1, or 0-100)")
        said = (f"{self.source}: spectral values read as percent (0-100) and divided by 100: {len(high)} of "
                f"{len(peaks)} patches reach above {FRACTION_MAX:g} (largest {top:g})")
        if low:
            shown = ", ".join(names[i] for i in low[:5]) + (" ..." if len(low) > 5 else "")
            said += (f"; {len(low)} stay below {FRACTION_MAX:g} % ({shown}): very dark patches, or values given as "
                     "factors? check them")
        self.warnings.append(said)
        log.warning("%s", said)
        return wl, values / 100.0

    def emission_table(self) -> SpectralTable:
        """Spectroradiometer readings (module docstring): wavelengths (n_wl,) x readings (n_wl, n_sets); a file
        of one reading without a name field is named after the file."""
        wl, values = self.spectral_values()
        meta = {k.lower(): v for k, v in self.keywords.items()}
        meta.setdefault("title", Path(self.source).stem)
        names = self.names()
        if len(self.rows) == 1 and not any(f.upper() in _NAME_FIELDS for f in self.fields):
            names = [Path(self.source).stem]
        return SpectralTable(wl, values, names, meta, self.source)


def is_cgats(path: str | Path) -> bool:
    """Whether ``path`` looks like a CGATS / X-Rite file (has a BEGIN_DATA_FORMAT line)."""
    try:
        return any(line.strip() == "BEGIN_DATA_FORMAT" for line in _text(Path(path)).splitlines())
    except SpectralDataError:
        return False


def _text(path: Path) -> str:
    try:
        size = path.stat().st_size
        if size > MAX_CGATS_BYTES:
            raise CgatsError(f"{path}: {size / 2 ** 20:.1f} MiB is too large for a CGATS file (limit "
                             f"{MAX_CGATS_BYTES // 2 ** 20} MiB)")
        data = path.read_bytes()
    except OSError as exc:
        raise CgatsError(f"{path}: cannot read file ({exc.strerror or exc})") from None
    for enc in ("utf-8-sig", "latin-1"):          # X-Rite writes Latin-1 degree signs
        try:
            return data.decode(enc)
        except UnicodeDecodeError:
            continue
    raise CgatsError(f"{path}: not a text file")  # pragma: no cover - latin-1 decodes any bytes


def _tokens(line: str, name: str, lineno: int) -> list[str]:
    try:
        return shlex.split(line, comments=True, posix=True)
    except ValueError as exc:
        raise CgatsError(f"{name}:{lineno}: {exc} (unbalanced quotes?)") from None


def read_cgats(path: str | Path) -> CgatsTable:
    """Parse a CGATS / X-Rite file: keywords, the data format's fields and the data rows (strings)."""
    path = Path(path)
    name = str(path)
    table = CgatsTable([], [], {}, name)
    state = "header"
    n_fields = n_sets = None
    end_line = 0
    for lineno, raw in enumerate(_text(path).splitlines(), start=1):
        line = raw.strip()
        end_line = lineno
        if not line or line.startswith("#"):
            continue
        if line in ("BEGIN_DATA_FORMAT", "END_DATA_FORMAT", "BEGIN_DATA", "END_DATA"):
            state = {"BEGIN_DATA_FORMAT": "format", "BEGIN_DATA": "data"}.get(line, "header")
            if line == "BEGIN_DATA" and not table.fields:
                raise CgatsError(f"{name}:{lineno}: BEGIN_DATA before any BEGIN_DATA_FORMAT ... END_DATA_FORMAT")
            continue
        tokens = _tokens(line, name, lineno)
        if state == "format":
            table.fields += tokens
        elif state == "data":
            if len(tokens) != len(table.fields):
                raise CgatsError(f"{name}:{lineno}: {len(tokens)} values, expected {len(table.fields)} "
                                 f"(one per field of BEGIN_DATA_FORMAT)")
            table.rows.append(tokens)
            table.row_lines.append(lineno)
        elif tokens:
            key, value = tokens[0], " ".join(tokens[1:])
            table.keywords.setdefault(key, value)
            if key in ("NUMBER_OF_FIELDS", "NUMBER_OF_SETS"):
                try:
                    number = int(value)
                except ValueError:
                    raise CgatsError(f"{name}:{lineno}: {key} {value!r} is not a whole number") from None
                n_fields, n_sets = (number, n_sets) if key == "NUMBER_OF_FIELDS" else (n_fields, number)
    if not table.fields:
        raise CgatsError(f"{name}:{end_line}: no BEGIN_DATA_FORMAT ... END_DATA_FORMAT section: not a CGATS file")
    if not table.rows:
        raise CgatsError(f"{name}:{end_line}: no data rows between BEGIN_DATA and END_DATA")
    if n_fields is not None and n_fields != len(table.fields):      # every row matched the format list above
        table.warnings.append(f"{name}: NUMBER_OF_FIELDS says {n_fields} but the data format lists "
                              f"{len(table.fields)} fields; the data rows match the list, read by it")
        log.warning("%s", table.warnings[-1])
    if n_sets is not None and n_sets != len(table.rows):
        raise CgatsError(f"{name}: NUMBER_OF_SETS says {n_sets} but {len(table.rows)} data rows follow "
                         f"(truncated file?)")
    log.debug("read %s: %d fields x %d sets", name, len(table.fields), len(table.rows))
    return table


def read_cgats_spectra(path: str | Path) -> SpectralTable:
    return read_cgats(path).spectral_table()


def read_cgats_emission(path: str | Path) -> SpectralTable:
    """Spectroradiometer readings from a CGATS / ArgyllCMS .sp / .ti3 file (one reading per data row)."""
    return read_cgats(path).emission_table()


def write_cgats_spectra(path: str | Path, wavelengths: np.ndarray, values: np.ndarray, names: list[str], *,
                        file_id: str = "CTI3", descriptor: str = "", keywords: dict[str, str] | None = None,
                        fmt: str = "%.8g", device_class: str = "EMISSION") -> Path:
    """Write spectra as a CGATS file with the ArgyllCMS spectral keywords (atomically).

    Parameters
    ----------
    path : the file (``.ti3``, ``.sp`` ...).
    wavelengths : (n_wl,) nm, evenly spaced (SPECTRAL_START_NM / SPECTRAL_END_NM / SPECTRAL_BANDS describe them).
    values : (n_wl, n) one spectrum per column, written as one data row each (SPECTRAL_NORM 1).
    names : n SAMPLE_ID values.
    file_id : the file's first line (``CTI3``, ``SPECT`` ...).
    keywords : further keywords (e.g. MEAS_TYPE, DUALRGB_UNITS), declared with KEYWORD as ArgyllCMS does.
    device_class : ArgyllCMS's DEVICE_CLASS (``spec2cie`` and ``colprof`` refuse a .ti3 without it): 'EMISSION'
        for a light source's readings, 'OUTPUT' for reflective samples, 'INPUT' for a chart read by a camera.

    Returns
    -------
    The path written.
    """
    wl = np.asarray(wavelengths, dtype=float)
    data = np.asarray(values, dtype=float).reshape(len(wl), -1)
    steps = np.diff(wl)
    if len(wl) < 2 or not np.allclose(steps, steps[0]):
        raise ValueError(f"{path}: CGATS spectral fields need evenly spaced wavelengths")
    if data.shape[1] != len(names):
        raise ValueError(f"{path}: {data.shape[1]} spectra but {len(names)} names")
    declared = {"SPECTRAL_BANDS": str(len(wl)), "SPECTRAL_START_NM": f"{wl[0]:.6f}",
                "SPECTRAL_END_NM": f"{wl[-1]:.6f}", "SPECTRAL_NORM": "1.000000", **(keywords or {})}
    lines = [file_id, "", f'DESCRIPTOR "{descriptor or "spectral data"}"', 'ORIGINATOR "dualrgb"',
             f'CREATED "{time.strftime("%a %b %d %H:%M:%S %Y")}"', f'DEVICE_CLASS "{device_class}"']
    for key, value in declared.items():
        lines += [f'KEYWORD "{key}"', f'{key} "{value}"']
    fields = ["SAMPLE_ID", *(f"SPEC_{w:g}" for w in wl)]
    lines += ["", f"NUMBER_OF_FIELDS {len(fields)}", "BEGIN_DATA_FORMAT", " ".join(fields), "END_DATA_FORMAT", "",
              f"NUMBER_OF_SETS {len(names)}", "BEGIN_DATA"]
    lines += [" ".join([f'"{name}"', *(fmt % v for v in data[:, j])]) for j, name in enumerate(names)]
    lines.append("END_DATA")
    return atomic_write(Path(path), "\n".join(lines) + "\n")
