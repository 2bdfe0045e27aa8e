#!/bin/sh
# System packages the tests need: OpenFOAM v1912 (Debian's openfoam) and ffmpeg (animations).
# Idempotent: does nothing when they are already there.
set -e
need=""
[ -f /usr/share/openfoam/etc/bashrc ] || need="$need openfoam"
command -v ffmpeg >/dev/null 2>&1 || need="$need ffmpeg"
[ -z "$need" ] && exit 0
SUDO=""
[ "$(id -u)" = 0 ] || SUDO="sudo"
echo "installing Debian packages:$need"
$SUDO apt-get update -q
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends $need
