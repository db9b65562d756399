#!/usr/bin/env bash
# The loop's independent client: python-can's slcan interface, on the pty the emulator
# creates (`scanhil-emulator serve --fsm slcan:pty`), runs lockstep periods against the
# emulated mirror node, encoding and decoding every frame with cantools and
# protocol/scanhil.dbc (ci/interop/slcan_vs_emulator.py says what it checks).
set -euo pipefail
cd "$(dirname "$0")/../.."
ci/interop/venv.sh
cargo build --quiet -p scanhil-emulator --bin scanhil-emulator
timeout 120 .venv/bin/python ci/interop/slcan_vs_emulator.py \
    target/debug/scanhil-emulator fixtures/scenes/loop-fast.json protocol/scanhil.dbc 400
