"""Processing of dual-RGB captures (Qt-free, numpy): darks, flat field, HDR, patches, characterisation, outputs.

Modules, in pipeline order (each has its own docstring with the thesis equations it implements):
  mosaic        Bayer helpers: superpixel RGB (no demosaic), row bands for tiled processing
  calibration   MasterDark (8.2.1, min/max-rejected mean per exposure time), FlatField / flat_field (eq 7.1)
  hdr           HdrMerge, triangle_weight (8.2.2 / 8.2.3; eq 8.9 or variance-optimal weights)
  kernels       fused numba kernels (dark combine, HDR accumulate, flat field + superpixel), warm_up()
  pipeline      CaptureProcessor, ExposureRef, ChannelStack, processor_from_session, TargetSpec, process_session
  patches       PatchGrid (any quadrilateral, trimmed means), detect_cc24 (optional colour-checker-detection)
  characterise  least-squares (eqs 5.2-5.6) and mean-dE00-optimised matrices, train/test evaluation
  outputs       XYZ / N-channel float32 TIFFs, 16-bit sRGB and ProPhoto TIFFs with ICC, CSVs
  report        JSON + PNG figures, Fig 7.4 DN validation, FADGI / ISO 19264-1 / Metamorfoze grading
"""
from app.processing.calibration import DarkFrame, FlatField, MasterDark, flat_field
from app.processing.characterise import Characterisation, MethodResult, characterise, fit_de2000, fit_least_squares, patch_errors
from app.processing.hdr import HdrMerge, HdrResult, triangle_weight
from app.processing.mosaic import row_bands, superpixel
from app.processing.patches import Cc24Detection, PatchGrid, PatchValues, detect_cc24
from app.processing.pipeline import (CaptureProcessor, ChannelStack, ExposureRef, SessionResult, TargetSpec,
                                     process_session, processor_from_session)

__all__ = [
    "DarkFrame", "FlatField", "MasterDark", "flat_field", "Characterisation", "MethodResult", "characterise",
    "fit_de2000", "fit_least_squares", "patch_errors", "HdrMerge", "HdrResult", "triangle_weight", "row_bands",
    "superpixel", "Cc24Detection", "PatchGrid", "PatchValues", "detect_cc24", "CaptureProcessor", "ChannelStack",
    "ExposureRef", "processor_from_session", "TargetSpec", "SessionResult", "process_session",
]
