#!/usr/bin/env bash
# Creates (or reuses) the Python venv at .venv with the pinned interop clients
# (ci/interop/requirements.txt). Run from anywhere; idempotent. On a fresh Debian machine
# without the venv module it installs python3-venv first (root and apt-get needed).
set -euo pipefail
cd "$(dirname "$0")/../.."
if [ ! -x .venv/bin/python ]; then
    if ! python3 -m venv .venv; then
        rm -rf .venv
        if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
            echo "interop: python3 has no venv module; installing python3-venv" >&2
            apt-get install -y -qq python3-venv >/dev/null
            python3 -m venv .venv
        else
            echo "interop: python3 -m venv failed; install python3-venv" >&2
            exit 1
        fi
    fi
fi
.venv/bin/python -m pip install --quiet --disable-pip-version-check -r ci/interop/requirements.txt
