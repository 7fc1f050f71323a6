"""Processing of dual-RGB captures (Qt-free, numpy): darks, flat field, HDR, patches, characterisation, outputs.

Modules, in pipeline order (each has its own docstring with the thesis equations it implements):
  mosaic        Bayer helpers: superpixel RGB (no demosaic), row bands for tiled processing
  calibration   MasterDark (8.2.1, min/max-rejected mean per exposure time), FlatField (eq 7.1)
  hdr           HdrMerge, triangle_weight (8.2.2 / 8.2.3; eq 8.9 or variance-optimal weights)
  kernels       fused numba kernels (dark combine, HDR accumulate, flat field + superpixel), warm_up()
  pipeline      CaptureProcessor, ExposureRef, ChannelStack (a whole session:
  app.workflow.calibration.session_processing)
  patches       PatchGrid (any quadrilateral, trimmed means), detect_cc24 (optional colour-checker-detection)
  characterise  least-squares (eqs 5.2-5.6) and mean-dE00-optimised matrices, train/test evaluation
  outputs       16-bit TIFFs (sRGB / ProPhoto with ICC, XYZ, N-channel) with TIFF tags and XMP, CSVs
  crf_analysis  camera response function and exposure-time linearity (ruptures)
  report        JSON + PNG figures, Fig 7.4 DN validation, FADGI / ISO 19264-1 / Metamorfoze grading

Import the modules themselves (this package imports nothing).
"""
