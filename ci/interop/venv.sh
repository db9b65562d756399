#!/usr/bin/env bash
# Creates (or reuses) the Python venv at .venv with the pinned interop clients
# (ci/interop/requirements.txt). Run from anywhere; idempotent.
set -euo pipefail
cd "$(dirname "$0")/../.."
if [ ! -x .venv/bin/python ]; then
    python3 -m venv .venv
fi
.venv/bin/python -m pip install --quiet --disable-pip-version-check -r ci/interop/requirements.txt
