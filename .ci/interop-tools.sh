#!/usr/bin/env bash
# The tools an archive reads the deliverables with, for the interop tests (tests/app/test_interop_tools.py,
# tests/drivers/test_dng_writer.py; each skips when its tool is absent): ArgyllCMS (iccdump), LittleCMS (tificc),
# ImageMagick, GDAL, exiftool, SLUB's checkit_tiff (tests/app/test_archival_masters.py); and the AVR toolchain and
# simavr for the LED sphere's reference firmware (make firmware-check: gcc-avr, avr-libc, simavr, libsimavr-dev,
# libsimavrparts1). Installed with apt-get where there is one (Debian / Ubuntu CI runners; sudo when not root);
# elsewhere the tests that need them skip and say which package to install.
set -euo pipefail
packages=(argyll liblcms2-utils imagemagick gdal-bin libimage-exiftool-perl checkit-tiff
          gcc-avr avr-libc simavr libsimavr-dev libsimavrparts1)
missing=()
for tool in iccdump tificc identify gdalinfo exiftool checkit_tiff avr-gcc simavr; do
    command -v "$tool" >/dev/null 2>&1 || missing+=("$tool")
done
[[ -f /usr/include/simavr/sim_avr.h ]] || missing+=("libsimavr-dev")
if [[ ${#missing[@]} -eq 0 ]]; then
    exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
    echo "interop-tools: no apt-get here; tests needing ${missing[*]} will skip" >&2
    exit 0
fi
sudo=""
[[ "$(id -u)" -eq 0 ]] || sudo="sudo -n"
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${packages[@]}" >/dev/null
