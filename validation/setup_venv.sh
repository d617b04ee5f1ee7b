#!/usr/bin/env bash
# Create validation/.venv and install the pinned requirements. Idempotent:
# does nothing if the venv exists and already satisfies requirements.txt.
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
VENV="$HERE/.venv"
REQ="$HERE/requirements.txt"
STAMP="$VENV/.requirements.sha256"

if [ ! -x "$VENV/bin/python" ]; then
    echo "creating $VENV"
    python3 -m venv "$VENV"
fi

want="$(sha256sum "$REQ" | cut -d' ' -f1)"
have="$(cat "$STAMP" 2>/dev/null || true)"
if [ "$want" = "$have" ] && "$VENV/bin/python" -c "import skfem, numpy, scipy, h5py, meshio, matplotlib, sksparse.cholmod, pyamg, vtkmodules.vtkIOXdmf2, pxr.Usd" 2>/dev/null; then
    echo "validation venv up to date ($VENV)"
    exit 0
fi

# scikit-sparse (benchmark peer) is built from source against the CHOLMOD headers.
if [ ! -f /usr/include/suitesparse/cholmod.h ]; then
    echo "installing libsuitesparse-dev (CHOLMOD headers for scikit-sparse)"
    SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
    { $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libsuitesparse-dev; } \
        || echo "warning: could not install libsuitesparse-dev; scikit-sparse will not build" >&2
fi
"$VENV/bin/python" -m pip install --quiet --upgrade pip
"$VENV/bin/python" -m pip install --quiet -r "$REQ"
echo "$want" > "$STAMP"
echo "validation venv ready ($VENV)"
