#!/usr/bin/env bash
# Coverage-guided runs of the fuzz targets under AFL++ (cargo-afl, stable Rust).
#
#   fuzz/afl.sh build                      instrumented release build (target/afl/)
#   fuzz/afl.sh run TARGET SECONDS [OUT]   one target for SECONDS (default OUT: fuzz/out)
#   fuzz/afl.sh all SECONDS [OUT]          every target, AFL_PARALLEL (default 2) at a time
#   fuzz/afl.sh summary [OUT]              a table of each run's fuzzer_stats
#   fuzz/afl.sh rss TARGET [OUT]           the largest peak RSS over the run's inputs
#
# Needs `cargo install cargo-afl` and `cargo afl config --build` once. Each run starts from
# fuzz/corpus/TARGET, limits the target's memory to AFL_MEM_MB (RLIMIT_AS, default 512 MB: an
# allocation beyond it aborts, which AFL counts as a crash) and each input to AFL_TIMEOUT_MS
# (default 2000 ms: longer is a hang). Crashes land in OUT/TARGET/default/crashes, hangs in
# .../hangs. Runs are niced: the machine is shared.
set -euo pipefail

cd "$(dirname "$0")/.."
mem_mb=${AFL_MEM_MB:-512}
timeout_ms=${AFL_TIMEOUT_MS:-2000}
binary=target/afl/release/scanhil-fuzz-afl
targets=(slcan candump ild_stream can_messages ild_commands ild_replies decode replay ply
  surfaces scenario documents)

# Headless, on a shared machine: no screen, no core binding, no core dumps through a pipe.
export AFL_NO_UI=1 AFL_NO_AFFINITY=1 AFL_SKIP_CPUFREQ=1 AFL_I_DONT_CARE_ABOUT_MISSING_CRASHES=1

build() {
  CARGO_TARGET_DIR=target/afl cargo afl build --release -p scanhil-fuzz --features afl
}

dictionary() {
  case "$1" in
    scenario | documents) echo "-x fuzz/dictionaries/json.dict" ;;
    slcan | decode) echo "-x fuzz/dictionaries/slcan.dict" ;;
    ild_commands | ild_replies) echo "-x fuzz/dictionaries/ild.dict" ;;
    ply) echo "-x fuzz/dictionaries/ply.dict" ;;
  esac
}

run() {
  local target=$1 seconds=$2 out=${3:-fuzz/out}
  [[ -x $binary ]] || { echo "no $binary: run fuzz/afl.sh build" >&2; exit 1; }
  mkdir -p "$out"
  # shellcheck disable=SC2046
  nice cargo afl fuzz -i "fuzz/corpus/$target" -o "$out/$target" -m "$mem_mb" -t "$timeout_ms" \
    -V "$seconds" $(dictionary "$target") -- "$binary" "$target" > "$out/$target.log" 2>&1
  echo "$target: $(stat_line "$out/$target/default/fuzzer_stats")"
}

stat_line() {
  awk -F' *: *' '{ s[$1] = $2 } END {
    printf "%s s, %s execs (%s/s), coverage %s, %s inputs, %s crashes, %s hangs, peak RSS %s MB\n",
      s["run_time"], s["execs_done"], s["execs_per_sec"], s["bitmap_cvg"], s["corpus_count"],
      s["saved_crashes"], s["saved_hangs"], s["peak_rss_mb"] }' "$1"
}

summary() {
  local out=${1:-fuzz/out}
  echo "| target | run time (s) | executions | exec/s | coverage (edges) | corpus | crashes | hangs | peak RSS (MB) |"
  echo "|---|---|---|---|---|---|---|---|---|"
  for target in "${targets[@]}"; do
    local stats=$out/$target/default/fuzzer_stats
    [[ -f $stats ]] || continue
    awk -F' *: *' -v t="$target" '{ s[$1] = $2 } END {
      printf "| `%s` | %s | %s | %s | %s (%s) | %s | %s | %s | %s |\n", t, s["run_time"],
        s["execs_done"], s["execs_per_sec"], s["bitmap_cvg"], s["edges_found"],
        s["corpus_count"], s["saved_crashes"], s["saved_hangs"], s["peak_rss_mb"] }' "$stats"
  done
}

# Replays every input the run kept (queue, crashes, hangs), one process each, and prints the
# largest peak RSS (kB, from /usr/bin/time) and the input that reached it.
rss() {
  local target=$1 out=${2:-fuzz/out} largest=0 worst=""
  for input in "$out/$target"/default/{queue,crashes,hangs}/id:*; do
    [[ -f $input ]] || continue
    local kb
    /usr/bin/time -f %M -o "$out/rss.txt" "$binary" "$target" < "$input" > /dev/null 2>&1 || true
    kb=$(tail -1 "$out/rss.txt")
    if ((kb > largest)); then largest=$kb worst=$input; fi
  done
  echo "$target: peak RSS $largest kB ($worst)"
}

case "${1:-}" in
  build) build ;;
  run) run "$2" "$3" "${4:-fuzz/out}" ;;
  all)
    at_once=${AFL_PARALLEL:-2}
    for ((i = 0; i < ${#targets[@]}; i += at_once)); do
      for ((j = i; j < i + at_once && j < ${#targets[@]}; j++)); do
        run "${targets[j]}" "$2" "${3:-fuzz/out}" &
      done
      wait
    done
    ;;
  summary) summary "${2:-fuzz/out}" ;;
  rss) rss "$2" "${3:-fuzz/out}" ;;
  *) sed -n '2,14p' "$0" >&2; exit 2 ;;
esac
