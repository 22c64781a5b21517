#!/usr/bin/env bash
# GDAL's Python bindings for the benchmarks' reference runs: Debian's python3-gdal,
# importable by the system /usr/bin/python3 (not by the project venv). Idempotent.
set -euo pipefail
if /usr/bin/python3 -c "from osgeo import gdal" 2>/dev/null; then
    exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
    SUDO="sudo"
fi
$SUDO apt-get update
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y gdal-bin python3-gdal
/usr/bin/python3 -c "from osgeo import gdal; print('GDAL', gdal.__version__)"
