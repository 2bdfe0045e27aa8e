#!/bin/sh
# Create the virtual environment the Makefile uses (.venv), on any Debian-like machine:
# root or a user, Debian's Python (PEP 668 "externally-managed-environment") or another.
# --system-site-packages: packages already installed system-wide (numpy, scipy... from Debian
# or a CI image) are reused, pip installs only what is missing.  Idempotent.
set -e
VENV=${1:-.venv}
PY=${PYTHON:-python3}
[ -x "$VENV/bin/python" ] && "$VENV/bin/python" -m pip --version >/dev/null 2>&1 && exit 0
rm -rf "$VENV"
if ! "$PY" -m venv --system-site-packages "$VENV" 2>/dev/null; then
    # Debian ships venv's ensurepip in a separate package (python3-venv / python3.X-venv)
    rm -rf "$VENV"
    SUDO=""
    [ "$(id -u)" = 0 ] || SUDO="sudo"
    ver=$("$PY" -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')
    echo "installing Debian's venv support (python3-venv python$ver-venv)"
    $SUDO apt-get update -q
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends \
        python3-venv "python$ver-venv" || \
        DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q python3-venv
    "$PY" -m venv --system-site-packages "$VENV"
fi
"$VENV/bin/python" -m pip install -q --upgrade pip >/dev/null 2>&1 || true
echo "virtual environment: $VENV (activate with: . $VENV/bin/activate)"
