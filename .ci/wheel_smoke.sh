#!/usr/bin/env bash
# Smoke test of the built wheel as a user gets it: build the wheel, install it into a fresh venv, and run the CLI
# from a folder outside the checkout (so nothing is imported from the source tree), with pidng absent.
#   dualrgb --version; simulate --method exhaustive --top 3; a tiny demo; raw-info on a DNG the virtual camera
#   wrote; then gphoto2 uninstalled: devices says in one line that tethering needs libgphoto2, raw-info still works.
# Called by `make test` (target wheel-smoke). PY is the interpreter the fresh venv is made from (default python3);
# the checkout's .venv builds the wheel (pip may use the machine's package index and cache).
#
# SMOKE_DIR (default ~/.cache/dualrgb/wheel-smoke/<checksum of the checkout's path>) holds the run: src/, dist/, venv/ and run/ are made afresh each
# time (left there for a look); numba-cache/ is kept, like pip's cache. The numba kernels take one to several
# minutes to compile in a fresh venv; numba reuses a cached kernel only for the same source path, size and mtime,
# so the venv lives at a fixed path and the installed sources get the wheel's recorded times: a later run whose
# sources did not change loads the kernels in seconds, a changed file is compiled again.
set -euo pipefail

repo="$(cd "$(dirname "$0")/.." && pwd)"
py="${PY:-python3}"
builder="$repo/.venv/bin/python"
[[ -x "$builder" ]] || builder="$py"
checkout_id="$(printf '%s' "$repo" | cksum | cut -d' ' -f1)"       # one folder per checkout: runs side by side
work="${SMOKE_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/dualrgb/wheel-smoke/$checkout_id}"
start=$SECONDS
step() { printf 'wheel-smoke [%3ds] %s\n' "$((SECONDS - start))" "$*"; }
fail() { echo "wheel-smoke: FAILED: $*" >&2; exit 1; }

step "clearing the last run in $work"
mkdir -p "$work/numba-cache"
trash="$work/trash.$$"                       # the old venv (many small files) is deleted in the background
mkdir "$trash"
for old in src dist venv run; do [[ -e "$work/$old" ]] && mv "$work/$old" "$trash/"; done
nohup rm -rf "$work"/trash.* >/dev/null 2>&1 &
mkdir -p "$work/src"
export NUMBA_CACHE_DIR="$work/numba-cache"

step "building the wheel"
# from a copy of what a clone holds (tracked and untracked-but-not-ignored files): pip builds in the source tree,
# and a stale build/ there could slip files into the wheel that the checkout no longer has
"$builder" - "$repo" "$work/src" <<'EOF'
import shutil, subprocess, sys
from pathlib import Path
repo, dst = (Path(a) for a in sys.argv[1:])
listed = subprocess.run(["git", "-C", str(repo), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                        capture_output=True, check=True).stdout.decode().split("\0")
for name in filter(None, listed):
    if (repo / name).is_file():                       # a tracked file deleted in the work tree is skipped
        (dst / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(repo / name, dst / name)
EOF
"$builder" -m pip wheel --quiet --no-deps --wheel-dir "$work/dist" "$work/src" >/dev/null
wheel="$(ls "$work"/dist/dualrgb-*.whl)"
step "installing $(basename "$wheel") into a fresh venv"
"$py" -m venv "$work/venv"
bin="$work/venv/bin"
"$bin/python" -m pip install --quiet --disable-pip-version-check --no-compile "$wheel" \
    2> >(grep -v "is ignored: it is neither a file nor a directory" >&2)      # no .pyc: faster; index noise off
"$bin/python" - "$wheel" <<'EOF'
import os, sys, sysconfig, time, zipfile
site = sysconfig.get_paths()["purelib"]
with zipfile.ZipFile(sys.argv[1]) as wheel:           # installed sources get the wheel's times (numba cache key)
    for info in wheel.infolist():
        path = os.path.join(site, info.filename)
        if info.filename.endswith(".py") and os.path.isfile(path):
            stamp = time.mktime(info.date_time + (0, 0, -1))
            os.utime(path, (stamp, stamp))
EOF
"$bin/python" -c "import importlib.util, sys; sys.exit(importlib.util.find_spec('pidng') is not None)" \
    || fail "pidng is installed in the fresh venv (it must not be a dependency)"

run="$work/run"                              # outside the checkout: the installed package is what runs
mkdir -p "$run"
cd "$run"
export DUALRGB_DATA_DIR="$run/user-data" PYTHONPATH="" QT_QPA_PLATFORM=offscreen
where="$("$bin/python" -c 'import dualrgb.app, os; print(os.path.dirname(dualrgb.app.__file__))')"
[[ "$where" == "$work/venv/"* ]] || fail "dualrgb.app imported from $where, not from the installed wheel"
step "one namespace: top_level.txt is dualrgb alone, nothing else at the top of site-packages"
top="$(cat "$work"/venv/lib/python*/site-packages/dualrgb-*.dist-info/top_level.txt 2>/dev/null || true)"
[[ "$top" == "dualrgb" ]] || fail "top_level.txt lists '$top', expected 'dualrgb' alone"
for name in app common drivers simulation resources tools; do
    "$bin/python" -c "import importlib.util, sys; sys.exit(importlib.util.find_spec('$name') is not None)" \
        || fail "the wheel installed a top-level '$name'"
done

expected="$(sed -n 's/^version = "\(.*\)"/\1/p' "$repo/pyproject.toml")"
step "dualrgb --version; python -m dualrgb --version"
version="$("$bin/dualrgb" --version)"
[[ "$version" == "dualrgb $expected" ]] || fail "--version printed '$version', expected 'dualrgb $expected'"
version="$("$bin/python" -m dualrgb --version)"
[[ "$version" == "dualrgb $expected" ]] || fail "python -m dualrgb --version printed '$version'"

step "dualrgb simulate --method exhaustive --top 3 (the first run compiles the numba kernels)"
"$bin/dualrgb" simulate --method exhaustive --top 3 --json sim.json > sim.txt
grep -q "(1, 6, 8)" sim.txt || fail "simulate did not rank thesis Table 5.1's pair: $(cat sim.txt)"
"$bin/python" - <<'EOF' || fail "sim.json lacks the format tag or versions"
import json
d = json.load(open("sim.json"))
assert d["format"] == "dualrgb-simulation/1" and d["software"]["numba"] and len(d["results"]) == 3, d.keys()
EOF

step "dualrgb demo (tiny: 128x96 frames, 4 darks, least squares)"
"$bin/dualrgb" demo --out demo --frame-size 128x96 --dark-frames 4 --no-de-fit > demo.txt 2> demo.err \
    || fail "demo: $(tail -3 demo.err)"
[[ -s demo/session/session.log ]] || fail "the demo's session has no session.log"
dng="$(ls demo/session/*.DNG | head -1)"
[[ -n "$dng" ]] || fail "the demo wrote no DNG"

step "dualrgb raw-info $(basename "$dng")"
"$bin/dualrgb" raw-info "$dng" --json info.json > info.txt
grep -q "RGGB" info.txt || fail "raw-info: $(cat info.txt)"

step "without gphoto2: devices names what tethering needs, raw-info still works"
"$bin/python" -m pip uninstall --quiet --yes gphoto2
"$bin/dualrgb" devices --no-probe --json - > devices.json || true       # exit 1 when nothing is attached
grep -q "tethering needs libgphoto2" devices.json || fail "devices without gphoto2: $(cat devices.json)"
"$bin/dualrgb" raw-info "$dng" > /dev/null

step "passed"
