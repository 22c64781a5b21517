#!/usr/bin/env bash
# Debian's Chromium and its WebDriver, for tests/test_livemap.py (the live map in a real
# headless browser). Nothing to do when both are there; root (CI) installs them with
# apt-get; elsewhere it says how, and the browser test reports itself skipped.
set -euo pipefail
if command -v chromium >/dev/null && command -v chromedriver >/dev/null; then
    exit 0
fi
packages=(chromium chromium-driver)
if [ "$(id -u)" = 0 ]; then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${packages[@]}"
elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then
    sudo apt-get update -qq
    sudo DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${packages[@]}"
else
    echo "note: the live-map browser test needs: apt-get install ${packages[*]}" >&2
    [ "${CI:-}" = true ] && exit 1
fi
exit 0
