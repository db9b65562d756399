#!/usr/bin/env bash
# Remakes the tables of docs/bench-scene.md: `scanhil identify` (open loop, and closed loop
# with the paper's PID) of the nominal scene, the bench-like scene, and the bench-like scene's
# mirror parts each switched on alone (the scene with `parts` cut by jq). Prints Markdown rows;
# the identify outputs stay in OUT_DIR (default out/bench-scene).
# Usage: docs/scripts/bench-scene-tables.sh [OUT_DIR]   (after cargo build --release)
#        TABLES_ONLY=1 docs/scripts/bench-scene-tables.sh [OUT_DIR]   (the tables of a past run)
set -euo pipefail
out=${1:-out/bench-scene}
bin=${SCANHIL:-./target/release/scanhil}
bench=fixtures/scenes/duplo-2x4-130mm-bench.json
mkdir -p "$out"

variant() { # name, parts (JSON array)
  jq --argjson parts "$2" '.name = "'"$1"'" | .parts = $parts' "$bench" > "$out/$1.json"
}
variant eq4-axes '["axes"]'
variant second_mode '["axes","second_mode"]'
variant cross_talk '["axes","cross_talk"]'
variant cross_talk_pickup '["axes","cross_talk","cross_talk_pickup"]'
variant amplifier '["axes","amplifier"]'
variant current_loop '["axes","amplifier","current_loop"]'
variant angle_sensor_bandwidth '["axes","angle_sensor_bandwidth"]'
variant angle_sensor_noise '["axes","angle_sensor_noise"]'
cp fixtures/scenes/duplo-2x4-130mm.json "$out/nominal.json"
cp "$bench" "$out/bench.json"

# identify ARGS...: retried up to three times (a lockstep run stops at the 2 s watchdog when
# the machine stalls a process that long; the figures do not depend on it).
identify() {
  for attempt in 1 2 3; do
    "$bin" identify --fsm pty "$@" > /dev/null && return 0
    echo "identify $* failed (attempt $attempt)" >&2
  done
  return 1
}

names="nominal bench eq4-axes second_mode cross_talk cross_talk_pickup amplifier current_loop angle_sensor_bandwidth angle_sensor_noise"
for name in $names; do
  [ -n "${TABLES_ONLY:-}" ] && break
  # Open loop in two bands: 0.05 A up to 100 Hz (the resonance near full range), 1 A above
  # (the response above the angle sensor's noise); 1/6 decade apart.
  identify --scene "$out/$name.json" --mode open-loop --axis alpha \
    --from-hz 10 --to-hz 100 --points 7 --amplitude 0.05 --settle-s 1 --cycles 4 \
    --blocks 4 --out "$out/$name-open-low.json"
  identify --scene "$out/$name.json" --mode open-loop --axis alpha \
    --from-hz 146.8 --to-hz 2154.4 --points 8 --amplitude 1 --settle-s 0.5 --cycles 40 \
    --blocks 4 --out "$out/$name-open-high.json"
  jq -s '.[0].points += .[1].points | .[0]' "$out/$name-open-low.json" \
    "$out/$name-open-high.json" > "$out/$name-open.json"
  identify --scene "$out/$name.json" --mode closed-loop \
    --controller fixtures/controllers/pid-series.json --axis alpha --from-hz 20 \
    --to-hz 1000 --points 40 --settle-s 0.2 --cycles 4 --blocks 4 \
    --out "$out/$name-closed.json"
done

echo "| scene | max err < 100 Hz dB | ~464 Hz dB / deg | 1000 Hz dB / deg | ~1468 Hz dB / deg | cross-axis 10 / 100 / 1000 / 2154 Hz dB | PID crossover Hz | phase margin deg | bandwidth Hz | peak dB at Hz |"
echo "|---|---|---|---|---|---|---|---|---|---|"
for name in $names; do
  jq -r --arg name "$name" --slurpfile closed "$out/$name-closed.json" '
    def r(n): (. * pow(10; n) | round) / pow(10; n);
    def at(f): [.points[]] | min_by((.measured.f_hz / f | log) | fabs);
    def err(f): at(f) | "\(.magnitude_error_db | r(2)) / \(.phase_error_deg | r(1))";
    def xt(f): at(f) | if .measured.cross_axis_db == null then "-"
      else (.measured.cross_axis_db - .measured.magnitude_db) | r(1) end;
    $closed[0].loop.measured as $l
    | "| \($name) | \([.points[] | select(.measured.f_hz < 100) | .magnitude_error_db | fabs] | max | r(3)) | \(err(464.2)) | \(err(1000)) | \(err(1468)) | \(xt(10)) / \(xt(100)) / \(xt(1000)) / \(xt(2154)) | \($l.crossover_hz | r(1)) | \($l.phase_margin_deg | r(1)) | \($l.bandwidth_hz | r(1)) | \($l.peak_db | r(2)) at \($l.peak_hz | r(0)) |"
  ' "$out/$name-open.json"
done
jq -r 'def r(n): (. * pow(10; n) | round) / pow(10; n);
  .loop.model as $m | "| model (eq. 4, the PID) | | | | | | \($m.crossover_hz | r(1)) | \($m.phase_margin_deg | r(1)) | \($m.bandwidth_hz | r(1)) | \($m.peak_db | r(2)) at \($m.peak_hz | r(0)) |"' "$out/nominal-closed.json"
