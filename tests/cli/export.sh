#!/usr/bin/env bash
# invr export (issue 43, item 8): a run's results written as a Mitsuba 3 scene with the optimised
# values (meshes as PLY, textures as EXR, transforms applied) and a job file over it; read back
# with `invr import`, and rendered equal to the run's final render up to Monte Carlo noise.
# usage: export.sh BIN_DIR WORK_DIR REPO_DIR
set -euo pipefail
BIN="$1"
DIR="$2"
REPO="$3"
rm -rf "$DIR"
mkdir -p "$DIR"
cd "$DIR"
fail() { echo "export: FAILED: $*"; exit 1; }
PY=/usr/bin/python3

# A texture under spot lights, three steps.
"$BIN/invr" run oxalis --steps 3 --target-spp 8 --workers 2 -o run > run.log 2>&1 || fail "run: $(tail -3 run.log)"
[ -s run/job.json ] || fail "the results have no job.json"
"$BIN/invr" export run -o exp/scene.xml > export.log 2> export.err || fail "export: $(cat export.err)"
grep -q "wrote .*scene.xml" export.log || fail "export said: $(cat export.log)"
# The check command export prints runs as printed (issue 61), with invr from this build.
check=$(sed -n 's/.*check with: invr //p' export.log)
[ -n "$check" ] || fail "export printed no check command: $(cat export.log)"
# shellcheck disable=SC2086
"$BIN/invr" $check > check.log 2>&1 || fail "the printed check command failed: invr $check: $(tail -3 check.log)"
[ -s exp/scene.json ] || fail "no job file beside the scene"
ls exp/meshes/*.ply > /dev/null || fail "no meshes written"
ls exp/textures/*.exr > /dev/null || fail "no textures written"
# Read back as any Mitsuba scene.
"$BIN/invr" import exp/scene.xml -o exp/imported.json > import.log 2>&1 || fail "import: $(cat import.log)"

# The exported scene's render against the run's final render (64 spp, the job's transport):
# independent estimates of the same image, so their squared difference over 8x8-pixel blocks is
# about the noise, which two renders of the exported scene with different seeds measure. A wrong
# value, texture orientation or light would add its bias on top.
for s in 1 2; do
  "$BIN/invr" render --scene exp/scene.xml --spp 64 --seed "$s" -o "b$s.exr" > /dev/null 2>&1 || fail "render of the exported scene"
done
$PY - run/final_view0.exr b1.exr b2.exr <<'PYEOF' || fail "the exported scene does not render like the final render"
import sys, numpy as np, OpenImageIO as oiio
a, b1, b2 = (oiio.ImageBuf(p).get_pixels(oiio.FLOAT)[..., :3] for p in sys.argv[1:])
def blocks(x):
    h, w = x.shape[0] // 8 * 8, x.shape[1] // 8 * 8
    return x[:h, :w].reshape(h // 8, 8, w // 8, 8, 3).mean(axis=(1, 3))
a, b1, b2 = blocks(a), blocks(b1), blocks(b2)
err, noise = np.mean((a - b1) ** 2), np.mean((b1 - b2) ** 2)
print(f"final vs exported: {err:.3e}; exported vs itself: {noise:.3e}; ratio {err / noise:.2f}; means {a.mean():.4f} {b1.mean():.4f}")
assert err < 2.0 * noise, "difference beyond the noise"
# And the image's mean, to its standard error (a few per cent of a value or a light shows here).
se = np.std(b1 - b2) / np.sqrt(b1.size)
assert abs(a.mean() - b1.mean()) < 4 * se, f"means differ by {abs(a.mean() - b1.mean()):.4f}, standard error {se:.4f}"
PYEOF

# The job over it runs, and carries the run's truth (issue 61): it renders its targets from it and
# starts at the run's final parameter error, not at 0 against the optimised values.
grep -q '"mitsuba"' exp/scene.json || fail "the job does not name the scene"
grep -q '"truth_values"' exp/scene.json || fail "the job does not carry the run's truth: $(cat exp/scene.json)"
if grep -q 'target_view0.exr' exp/scene.json; then fail "a job with its truth names the run's target images"; fi
grep -q "keeps the run's truth" export.err || fail "export did not say which truth the job has: $(cat export.err)"
"$BIN/invr" optimize exp/scene.json --steps 1 --final-spp 4 -o continued > continued.log 2>&1 || fail "optimize the exported job: $(tail -3 continued.log)"
$PY - run/convergence.csv continued.log <<'PYEOF' || fail "the exported job does not start at the run's final parameter error"
import csv, re, sys
rows = list(csv.DictReader(open(sys.argv[1])))
run = float(rows[-1]["param_error"])
m = re.search(r"parameter error ([0-9.e+-]+) ->", open(sys.argv[2]).read())
assert m, "optimize printed no parameter error"
start = float(m.group(1))
print(f"run's final parameter error {run:.6g}; the exported job's start {start:.6g}")
assert run > 0 and abs(start - run) <= 1e-3 * run, (run, start)
PYEOF
"$BIN/invr" run exp/scene.json --steps 1 --workers 2 --final-spp 4 -o again > again.log 2>&1 || fail "the exported job does not run: $(tail -3 again.log)"

# A Mitsuba scene with meshes of its own, its parameters in Mitsuba's names (the light is named
# after its shape, whose id the export must change): the service knew the meshes by content hash,
# so export asks for their folder, then finds them there; the job file names what it optimises
# in the exported scene's names.
"$BIN/invr" run "$REPO/docs/examples/mitsuba/cornell-optimize.json" -D res=32 -D max_depth=3 --steps 2 --target-spp 8 --workers 2 \
  --param red.reflectance.value=0.01,0.2,0.9 --param light.emitter.radiance.value \
  -o run2 > run2.log 2>&1 || fail "run of the Mitsuba job: $(tail -3 run2.log)"
if "$BIN/invr" export run2 -o exp2/scene.xml > /dev/null 2> export2.err; then fail "export found uploaded meshes without --assets"; fi
grep -q "\-\-assets" export2.err || fail "the error does not say --assets: $(cat export2.err)"
"$BIN/invr" export run2 -o exp2/scene.xml --assets "$REPO/docs/examples/mitsuba" > /dev/null 2> export2.err || fail "export with --assets: $(cat export2.err)"
"$BIN/invr" render --scene exp2/scene.xml --spp 4 -o c.exr > /dev/null 2>&1 || fail "render of the exported Mitsuba scene"
"$BIN/invr" plan exp2/scene.json > plan2.log 2>&1 || fail "the exported Mitsuba job does not load: $(cat plan2.log)"
grep -q '"lights/light/intensity"' exp2/scene.json || fail "the job does not name the light in the exported scene's names"
# A job exported as it is described (issue 58: the scenes deploy/peers.sh gives Mitsuba 3): the
# scene is the ground truth, the job keeps its starting values and renders its targets.
"$BIN/invr" export cornell -o zoo/scene.xml > zoo.log 2>&1 || fail "export of a zoo job: $(cat zoo.log)"
grep -q '"initial": 0.5' zoo/scene.json || fail "the exported zoo job lost its initial values: $(cat zoo/scene.json)"
if grep -q '"targets"' zoo/scene.json; then fail "the exported zoo job names targets"; fi
"$BIN/invr" plan zoo/scene.json > zplan.log 2>&1 || fail "the exported zoo job does not load: $(cat zplan.log)"
for s in 1 2; do
  "$BIN/invr" render --scene zoo/scene.xml --spp 16 --seed "$s" -o "z$s.exr" > /dev/null 2>&1 || fail "render of the exported zoo scene"
done
"$BIN/invr" render --scene cornell --spp 16 --seed 3 -o zc.exr > /dev/null 2>&1 || fail "render of the zoo scene"
$PY - zc.exr z1.exr z2.exr <<'PYEOF' || fail "the exported zoo scene does not render like the zoo scene"
import sys, numpy as np, OpenImageIO as oiio
a, b1, b2 = (oiio.ImageBuf(p).get_pixels(oiio.FLOAT)[..., :3] for p in sys.argv[1:])
def blocks(x):
    h, w = x.shape[0] // 8 * 8, x.shape[1] // 8 * 8
    return x[:h, :w].reshape(h // 8, 8, w // 8, 8, 3).mean(axis=(1, 3))
a, b1, b2 = blocks(a), blocks(b1), blocks(b2)
err, noise = np.mean((a - b1) ** 2), np.mean((b1 - b2) ** 2)
print(f"zoo vs exported zoo: {err:.3e}; exported vs itself: {noise:.3e}; ratio {err / noise:.2f}")
assert err < 2.0 * noise, "difference beyond the noise"
PYEOF
if "$BIN/invr" export no_such_scene -o bad/scene.xml > bad.log 2>&1; then fail "export of an unknown job succeeded"; fi
echo "export: ok"
