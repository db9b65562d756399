#!/usr/bin/env bash
# The wire protocol's independent-client checks (cantools, python-can), on the project's own
# writers: regenerates the golden candump recording and checks it matches the committed one,
# decodes it with cantools and python-can against `scanhil decode`, and runs python-can's
# slcan interface on a real pty against the project's SLCAN codec.
set -euo pipefail
cd "$(dirname "$0")/../.."
ci/interop/venv.sh
cargo build --quiet -p scanhil-controller --bin scanhil
cargo build --quiet -p scanhil-protocol --example write-candump --example slcan-pty-peer
scanhil=target/debug/scanhil
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

target/debug/examples/write-candump "$work/lockstep.log"
if ! diff -u fixtures/recordings/lockstep-golden.log "$work/lockstep.log"; then
    echo "interop: the candump writer's output differs from fixtures/recordings/lockstep-golden.log" >&2
    echo "         (regenerate: cargo run -p scanhil-protocol --example write-candump -- fixtures/recordings/lockstep-golden.log)" >&2
    exit 1
fi
.venv/bin/python ci/interop/candump_cantools.py "$scanhil" "$work/lockstep.log" protocol/scanhil.dbc
timeout 120 .venv/bin/python ci/interop/slcan_python_can.py \
    target/debug/examples/slcan-pty-peer "$scanhil" protocol/scanhil.dbc
