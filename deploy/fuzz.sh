#!/usr/bin/env bash
# Builds the libFuzzer targets (tests/fuzz/, clang with ASan + UBSan) into ./build-fuzz and runs
# each for a bounded time on a scratch copy of its seed corpus:
#
#   bash deploy/fuzz.sh                       # every target, FUZZ_SECONDS (default 25) each
#   FUZZ_SECONDS=300 bash deploy/fuzz.sh fuzz_ply fuzz_obj   # some targets, longer
#   FUZZ_SECONDS=0 bash deploy/fuzz.sh        # build, run each corpus input once, no fuzzing
#   FUZZ_SEED=0 FUZZ_SECONDS=600 bash deploy/fuzz.sh   # a random seed (the default, 1, repeats)
#
# Targets: fuzz_obj fuzz_ply fuzz_png fuzz_exr fuzz_hdr fuzz_job_json fuzz_mitsuba_xml fuzz_task_result.
# New inputs go to build-fuzz/corpus/<target>/ (kept between runs, never into the repository);
# crashes to build-fuzz/artifacts/<target>-crash-*, with the log in build-fuzz/logs/<target>.log.
# Reproduce one with `build-fuzz/bin/<target> <file>`; INVR_FUZZ_VERBOSE=1 says why inputs are rejected.
# Targets run FUZZ_JOBS at a time (default: one per core; each is single-threaded).
# Prints one line per target and `fuzz: N passed, M failed`; exits 1 if any target failed.
set -euo pipefail
cd "$(dirname "$0")/.."

ALL_TARGETS=(fuzz_obj fuzz_ply fuzz_png fuzz_exr fuzz_hdr fuzz_job_json fuzz_mitsuba_xml fuzz_task_result)
TARGETS=("$@")
[ ${#TARGETS[@]} -eq 0 ] && TARGETS=("${ALL_TARGETS[@]}")
SECONDS_PER_TARGET="${FUZZ_SECONDS:-25}"
BUILD=build-fuzz
# Shared machines serialise builds on this lock (a no-op when nobody else holds it).
LOCK=(flock /tmp/invr-build.lock)
command -v flock > /dev/null || LOCK=()

CC="${FUZZ_CC:-clang}"
CXX="${FUZZ_CXX:-clang++}"
command -v "$CXX" > /dev/null || { echo "fuzz: $CXX not found (bash deploy/setup.sh installs clang)"; exit 1; }

t0=$(date +%s)
mkdir -p "$BUILD"
if [ ! -f "$BUILD/build.ninja" ]; then
  LAUNCHER=()
  command -v ccache > /dev/null && LAUNCHER=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
  CC="$CC" CXX="$CXX" "${LOCK[@]}" cmake -S . -B "$BUILD" -G Ninja -DINVR_FUZZ=ON -DCMAKE_BUILD_TYPE=Debug \
    "${LAUNCHER[@]}" > "$BUILD/configure.log" 2>&1 || { cat "$BUILD/configure.log"; exit 1; }
fi
# -k 0: a parser that does not compile fails its own target only; the others still run.
build_ok=1
"${LOCK[@]}" ninja -C "$BUILD" -k 0 "${TARGETS[@]}" > "$BUILD/build.log" 2>&1 || build_ok=0
if [ "$build_ok" -eq 1 ]; then
  echo "fuzz: built ${#TARGETS[@]} target(s) in $(( $(date +%s) - t0 )) s (log in $BUILD/build.log)"
else
  echo "fuzz: build errors ($(( $(date +%s) - t0 )) s, log in $BUILD/build.log):"
  grep -E "error|FAILED" -A3 "$BUILD/build.log" | head -40
fi

# halt_on_error: the first report ends the run (and saves the input). Leak checking stays on:
# libFuzzer reports an input whose run leaks (library leaks: tests/fuzz/lsan.supp).
export ASAN_OPTIONS="${ASAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}"
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$PWD/tests/fuzz/lsan.supp:print_suppressions=0}"

mkdir -p "$BUILD/artifacts" "$BUILD/logs" "$BUILD/corpus"
# One target: fuzz it, then write its verdict to $BUILD/logs/<target>.result ("ok <line>" or
# "FAILED <line>"). Each target is single-threaded, so FUZZ_JOBS of them (default: one per core)
# run at once; every target still gets its FUZZ_SECONDS of CPU.
fuzz_one() {
  local t="$1"
  local seeds="tests/fuzz/corpus/$t" corpus="$BUILD/corpus/$t" log="$BUILD/logs/$t.log" result="$BUILD/logs/$t.result"
  rm -f "$result"
  # Never a stale binary: a target whose build failed above still has work to do.
  if [ "$build_ok" -eq 0 ] && ! ninja -C "$BUILD" -n "$t" 2> /dev/null | grep -q "no work to do"; then
    rm -f "$log"
    printf 'FAILED fuzz: %-17s FAILED does not build (see %s)\n' "$t" "$BUILD/build.log" > "$result"
    return
  fi
  mkdir -p "$corpus"
  [ -d "$seeds" ] && cp "$seeds"/* "$corpus"/ 2> /dev/null || true
  # A fixed seed (FUZZ_SEED, default 1) makes a run from the committed seeds explore the same
  # inputs every time, so CI on a fresh clone is a repeatable gate; FUZZ_SEED=0 picks a random
  # seed, for longer hunts by hand.
  local args=(-max_total_time="$SECONDS_PER_TARGET" -seed="${FUZZ_SEED:-1}" -rss_limit_mb=2048 -timeout=10 -print_final_stats=1
              -artifact_prefix="$BUILD/artifacts/$t-")
  [ "$t" = fuzz_job_json ] && args+=(-dict=tests/fuzz/job_json.dict)
  [ "$t" = fuzz_mitsuba_xml ] && args+=(-dict=tests/fuzz/mitsuba_xml.dict)
  # FUZZ_SECONDS=0: run every input of the corpus once, no fuzzing.
  [ "$SECONDS_PER_TARGET" = 0 ] && args=(-runs=0 -rss_limit_mb=2048 -timeout=10 -print_final_stats=1
                                         -artifact_prefix="$BUILD/artifacts/$t-")
  # The image targets run through OpenImageIO, which leaks in its own error paths (see
  # tests/fuzz/lsan.supp): full stacks on every allocation (about 3x slower) so that the
  # suppressions can name the library's frames; leak checking stays on for invr's code.
  local asan="$ASAN_OPTIONS"
  case "$t" in fuzz_png|fuzz_exr|fuzz_hdr) asan="$asan:fast_unwind_on_malloc=0" ;; esac
  local rc=0
  ASAN_OPTIONS="$asan" "$BUILD/bin/$t" "${args[@]}" "$corpus" > "$log" 2>&1 || rc=$?
  local runs rate added cov
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  added=$(sed -n 's/^stat::new_units_added: *//p' "$log" | tail -1)
  cov=$(grep -oE 'cov: [0-9]+ ft: [0-9]+' "$log" | tail -1 || true)
  if [ "$rc" -eq 0 ]; then
    printf 'ok fuzz: %-17s ok     %9s runs %7s exec/s %5s new inputs  %s\n' "$t" "${runs:-?}" "${rate:-?}" "${added:-?}" "${cov:-}" > "$result"
  else
    local artifact kind
    artifact=$(sed -n 's/.*Test unit written to \(.*\)$/\1/p' "$log" | tail -1)
    # The first report in the log: a broken FUZZ_CHECK, an uncaught exception, UBSan, ASan, LSan
    # or libFuzzer's own (timeout, out-of-memory, deadly signal).
    kind=$(grep -m1 -oE 'fuzz invariant violated: .*|terminate called .*|runtime error: .*|ERROR: (AddressSanitizer|LeakSanitizer|libFuzzer|UndefinedBehaviorSanitizer): [a-z-]+( [a-z-]+)?' "$log" || true)
    [ -z "$kind" ] && kind="exit code $rc"
    { printf 'FAILED fuzz: %-17s FAILED %s\n' "$t" "$kind"
      printf '      input: %s\n      log:   %s\n' "${artifact:-(none written)}" "$log"; } > "$result"
  fi
}
JOBS="${FUZZ_JOBS:-$(nproc)}"
running=0
for t in "${TARGETS[@]}"; do
  if [ "$running" -ge "$JOBS" ]; then
    wait -n || true
    running=$((running - 1))
  fi
  fuzz_one "$t" &
  running=$((running + 1))
done
wait || true
passed=0
failed=0
failures=()
for t in "${TARGETS[@]}"; do
  result="$BUILD/logs/$t.result"
  if [ -f "$result" ] && head -1 "$result" | grep -q '^ok '; then
    passed=$((passed + 1))
  else
    failed=$((failed + 1))
    failures+=("$t")
  fi
  [ -f "$result" ] && sed '1s/^[a-zA-Z]* //' "$result" || echo "fuzz: $t: no result (the run was interrupted)"
done
echo "fuzz: $passed passed, $failed failed ($(( $(date +%s) - t0 )) s)"
if [ "$failed" -gt 0 ]; then
  echo "fuzz: failing targets: ${failures[*]}"
  for t in "${failures[@]}"; do
    [ -f "$BUILD/logs/$t.log" ] || continue
    echo "---- $t: the first report (whole log in $BUILD/logs/$t.log)"
    grep -m1 -A25 -E 'ERROR: |runtime error:|fuzz invariant violated|terminate called|deadly signal' "$BUILD/logs/$t.log" | head -40 || true
  done
  exit 1
fi
