#!/bin/bash
# Where a gradient step's time goes: perf's self time per function (and per library) over many
# consecutive gradient steps of one zoo job, as docs/performance.md's profiles were taken. The
# workload is `invr-lab bench step --no-replay`: one engine through the job's burn-in and 2 warm-up
# steps, then REPEATS steps; no ray log or replays; the targets at 4 spp so that rendering them is
# a small part of the profile.
# Usage: tests/bench/profile_step.sh BIN_DIR SCENE [METHOD] [REPEATS]
set -euo pipefail
bin=${1:?usage: profile_step.sh BIN_DIR SCENE [METHOD] [REPEATS]}
scene=${2:?usage: profile_step.sh BIN_DIR SCENE [METHOD] [REPEATS]}
method=${3:-}
repeats=${4:-200}
data=$(mktemp /tmp/invr-perf.XXXXXX)
trap 'rm -f "$data"' EXIT
perf record -q -F 1999 -o "$data" "$bin/invr-lab" bench step --scene "$scene" ${method:+--method "$method"} \
  --repeats "$repeats" --warmup 2 --target-spp 4 --no-replay > /dev/null
echo "# $scene ${method:-(method of the job)}: self time by library"
perf report -i "$data" --no-children --sort dso --stdio 2> /dev/null | grep -E '^ +[0-9]' | head -8
echo "# by function (>= 1 %)"
perf report -i "$data" --no-children --sort dso,sym --stdio --percent-limit 1 2> /dev/null | grep -E '^ +[0-9]'
