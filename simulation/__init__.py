"""Qt-free spectral simulation of dual-RGB capture: spectra, camera model (eq 5.10), characterisation,
colour metrics, exhaustive search and optimisers (PSO, GA). Imports nothing from app/ or Qt."""
