#!/usr/bin/env bash
# Usage:
#   bash deploy/test.sh             Builds with warnings as errors into build/, runs the default
#                                   test suite (unit, CLI, integration; every test but those
#                                   labelled `deep`) with ctest, then the fuzz targets for
#                                   FUZZ_SECONDS each (deploy/fuzz.sh: clang, ASan + UBSan, into
#                                   build-fuzz/; 25 s each by default, two at a time, 0 only replays
#                                   the seeds), then the evaluation suite's smoke run. About 20
#                                   minutes on 2 cores from a fresh clone.
#   bash deploy/test.sh --deep      Builds as above and runs the deep suite (ctest -L deep): the
#                                   statistical tests at full evaluation counts and the long
#                                   diagnostics. Must pass at the close of any change to core/diff,
#                                   core/restir or core/render. No fuzzing, no eval smoke run.
#   bash deploy/test.sh --sanitize  Builds everything with GCC under AddressSanitizer and
#                                   UndefinedBehaviorSanitizer (-DINVR_SANITIZE=ON) into build-asan/
#                                   and runs the default suite there. No fuzzing, no eval smoke run
#                                   (too slow instrumented). Takes much longer than the plain build.
# Every run ends with the ten slowest tests and the suite's total (tests/report_times.py).
set -euo pipefail
cd "$(dirname "$0")/.."

SANITIZE=0
DEEP=0
for arg in "$@"; do
  case "$arg" in
    --sanitize) SANITIZE=1 ;;
    --deep) DEEP=1 ;;
    -h|--help) sed -n '2,19p' "$0"; exit 0 ;;
    *) echo "test.sh: unknown option '$arg' (see the usage at the top of deploy/test.sh)" >&2; exit 2 ;;
  esac
done
if [ "$SANITIZE" -eq 1 ] && [ "$DEEP" -eq 1 ]; then
  echo "test.sh: --sanitize and --deep are separate runs; use one" >&2
  exit 2
fi
t0=$(date +%s)

bash deploy/setup.sh

# ctest in `dir` with `args`; the ten slowest tests and the total from its JUnit report, whatever
# the outcome, then ctest's own exit status.
run_ctest() {
  local dir="$1"
  shift
  local junit="$PWD/$dir/ctest-junit.xml" code=0 t=$(date +%s)
  rm -f "$junit"
  # The whole output of passing tests goes into the report too (ctest keeps 1 KB by default), so
  # every printed power and reference is there to read.
  (cd "$dir" && ctest --output-on-failure -j"$(nproc)" --test-output-size-passed 262144 --output-junit "$junit" "$@") || code=$?
  /usr/bin/python3 tests/report_times.py "$junit" "$(( $(date +%s) - t ))" || true
  return "$code"
}

if [ "$SANITIZE" -eq 1 ]; then
  # Warnings are not errors here: GCC's sanitizer instrumentation brings false positives
  # (-Wmaybe-uninitialized and friends); the plain build enforces -Werror.
  mkdir -p build-asan
  CC=gcc CXX=g++ cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=Release -DINVR_SANITIZE=ON > build-asan/build.log 2>&1 ||
    { cat build-asan/build.log; exit 1; }
  ninja -C build-asan >> build-asan/build.log 2>&1 || { grep -E "error|FAILED" -A5 build-asan/build.log | head -80; exit 1; }
  echo "build-asan: ok (log in build-asan/build.log)"
  # Any report fails its test: UBSan does not recover (-fno-sanitize-recover), ASan halts.
  # Leak checking stays on; the leaks that gRPC, TBB and the other libraries leave at exit on
  # purpose (process-lifetime singletons, thread-local caches) are suppressed by name in
  # tests/sanitize/lsan.supp, so a leak in invr's own code still fails the test that shows it.
  export ASAN_OPTIONS="halt_on_error=1:print_stacktrace=1:detect_leaks=1"
  export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
  export LSAN_OPTIONS="suppressions=$PWD/tests/sanitize/lsan.supp:print_suppressions=0"
  # Leases in the service tests must cover a healthy worker's longest task: three times longer here.
  export INVR_TEST_TIME_SCALE=3
  run_ctest build-asan -LE deep
  exit 0
fi

tb=$(date +%s)
bash deploy/build.sh -DINVR_WERROR=ON
echo "build: $(( $(date +%s) - tb )) s"
if [ "$DEEP" -eq 1 ]; then
  run_ctest build -L deep
  echo "test.sh --deep: done in $(( $(date +%s) - t0 )) s"
  exit 0
fi
run_ctest build -LE deep
# Every parser a user's bytes reach, fuzzed for a bounded time (about 2 minutes in all).
bash deploy/fuzz.sh
# The evaluation suite's smoke run (`invr-lab eval --quick`, about two minutes); the full suite is run
# by hand: see tests/bench/README.md.
bash tests/bench/eval_smoke.sh build/bin build/eval-quick
echo "test.sh: done in $(( $(date +%s) - t0 )) s"
