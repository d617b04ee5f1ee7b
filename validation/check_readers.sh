#!/usr/bin/env bash
# icefem's files read by readers that are not icefem's (part of `make test`):
#   - the Python reader's tests (python/tests, against runs of the built binary);
#   - check_xdmf.py: a fractured run's XDMF sidecars through VTK's XDMF reader;
#   - check_export.py: that run exported to USD, OBJ, PLY and VTU, read with pxr.Usd, meshio
#     and VTK's XML reader; and a run frozen by conduction (temperatures, a time-lapse stage).
# Needs target/release/icefem (`cargo test --release` builds it). Creates target/readers-venv
# from validation/requirements-readers.txt (wheels only) the first time.
#
#   validation/check_readers.sh
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
ICEFEM="$ROOT/target/release/icefem"
VENV="$ROOT/target/readers-venv"
REQ="$ROOT/validation/requirements-readers.txt"
[ -x "$ICEFEM" ] || { echo "error: $ICEFEM is missing: run cargo build --release first" >&2; exit 1; }

if ! python3 -c "import ensurepip, venv" 2>/dev/null; then
    echo "installing python3-venv (to create the readers' venv)"
    SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq python3-venv
fi
STAMP="$VENV/.requirements.sha256"
want="$(sha256sum "$REQ" | cut -d' ' -f1)"
if [ "$(cat "$STAMP" 2>/dev/null || true)" != "$want" ]; then
    echo "creating $VENV"
    rm -rf "$VENV"
    python3 -m venv "$VENV"
    "$VENV/bin/python" -m pip install --quiet --upgrade pip
    "$VENV/bin/python" -m pip install --quiet --only-binary=:all: -r "$REQ"
    echo "$want" > "$STAMP"
fi
PY="$VENV/bin/python"

WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT

echo "== the Python reader's tests"
(cd "$WORK" && ICEFEM_BIN="$ICEFEM" PYTHONPATH="$ROOT/python" "$PY" -m pytest -q -p no:cacheprovider "$ROOT/python/tests")

echo "== a fractured run (the paper's scene to 30 s) for the XDMF and export checks"
"$ICEFEM" -q run "$ROOT/scenes/freezing_container_fracture.toml" --end-time 30 --output "$WORK/paper.h5"
"$PY" "$ROOT/validation/check_xdmf.py" "$WORK/paper.h5"
for format in usd obj ply vtu; do
    "$ICEFEM" -q export "$WORK/paper.h5" --format "$format" --frames 0::5
done
"$PY" "$ROOT/validation/check_export.py" "$WORK/paper.h5" --frames 0::5

echo "== a run frozen by conduction (the thermal container to 30 min): temperatures in every export, a time-lapse stage"
"$ICEFEM" -q run "$ROOT/scenes/freezing_container_thermal.toml" --end-time 1800 --output "$WORK/thermal.h5"
for format in obj ply vtu; do
    "$ICEFEM" -q export "$WORK/thermal.h5" --format "$format"
done
"$ICEFEM" -q export "$WORK/thermal.h5" --format usd --speed 60
"$PY" "$ROOT/validation/check_export.py" "$WORK/thermal.h5"
