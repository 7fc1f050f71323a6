"""The lights other than the characterisation's D65 that a spectral estimate is judged under
(simulation.spectral_metrics: CIEDE2000 under each) and that a delivered spectral image can be rendered under
(app.processing.render): CIE D65, A, D50, FL11 and a measured warm-white museum LED. One table, colour-science
data; imports nothing heavy (the command line's ``--render-illuminant`` choices come from here).

References
----------
CIE 15:2018 (illuminants A, D50, D65, FL11); colour-science's ``SDS_LIGHT_SOURCES['Luxeon WW 2880']`` (a measured
2880 K phosphor-converted white LED, the kind museum galleries are lit with).
"""
from __future__ import annotations

import logging

log = logging.getLogger(__name__)

REFERENCE_LIGHT = "D65"     # the characterisation's reference illuminant: the default a delivery is rendered under
# name shown -> (colour-science collection, key); D65 first: the reference illuminant of the characterisation
OTHER_LIGHTS = {"D65": ("illuminant", "D65"), "A": ("illuminant", "A"), "D50": ("illuminant", "D50"),
                "FL11": ("illuminant", "FL11"), "LED 2880 K": ("light source", "Luxeon WW 2880")}


def light_key(name: str) -> str:
    """The command-line name of a light of :data:`OTHER_LIGHTS`: its first word ('LED 2880 K' -> 'LED')."""
    return name.split()[0]


def light_keys() -> dict[str, str]:
    """Command-line name -> light name, in :data:`OTHER_LIGHTS` order (D65 first)."""
    return {light_key(name): name for name in OTHER_LIGHTS}


def light_of_key(key: str) -> str:
    """The light named ``key`` (its command-line name in any case, or its full name) -> the light name of
    :data:`OTHER_LIGHTS`; anything else is a one-line ValueError naming the choices."""
    for k, name in light_keys().items():
        if key.strip().lower() in (k.lower(), name.lower()):
            return name
    choices = ", ".join(f"{k} ({v})" if k != v else k for k, v in light_keys().items())
    raise ValueError(f"light {key!r}: expected one of {choices}")
