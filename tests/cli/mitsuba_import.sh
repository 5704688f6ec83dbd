#!/usr/bin/env bash
# Mitsuba 3 scenes through the CLI: render, import, optimise with --param, plan, run on the
# embedded service, and bad files (exit 1, naming file, line and element).
# Usage: mitsuba_import.sh BIN_DIR WORK_DIR
set -euo pipefail
BIN="$(cd "$1" && pwd)/invr"
WORK="$2"
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
BOX="$ROOT/docs/examples/mitsuba/cornell-box.xml"
rm -rf "$WORK" && mkdir -p "$WORK"
fail() { echo "FAIL: $*" >&2; exit 1; }

echo "-- render an XML scene, with -D overrides"
"$BIN" render --scene "$BOX" -D res=32 -D spp=4 -o "$WORK/box.png" | grep -q "wrote .*box.png (32x32, view 0, 4 spp" || fail "render"

echo "-- import writes a job whose asset paths resolve from its own folder"
mkdir -p "$WORK/elsewhere"
"$BIN" import "$BOX" -D res=16 -o "$WORK/elsewhere/box.json" > "$WORK/import.log" 2> "$WORK/import.err"
grep -q "wrote .*box.json (8 shapes, 4 materials, 1 lights, 1 views" "$WORK/import.log" || { cat "$WORK/import.log"; fail "import summary"; }
grep -q '"path": "/.*/docs/examples/mitsuba/meshes/cbox_floor.obj"' "$WORK/elsewhere/box.json" || fail "import: far assets get absolute paths"
"$BIN" import "$BOX" -o "$WORK/box_here.json" > /dev/null 2>&1
cp -r "$ROOT/docs/examples/mitsuba" "$WORK/copy" && "$BIN" import "$WORK/copy/cornell-box.xml" -o "$WORK/copy/job.json" > /dev/null 2>&1
grep -q '"path": "meshes/cbox_floor.obj"' "$WORK/copy/job.json" || fail "import: assets beside the job get relative paths"
(cd / && "$BIN" render --scene "$WORK/elsewhere/box.json" --spp 2 -o "$WORK/box_json.png" > /dev/null) || fail "render the imported job"
"$BIN" import "$BOX" 2> /dev/null | grep -q '"materials"' || fail "import to stdout"

echo "-- an XML scene needs --param to be optimised; with it, it runs (Mitsuba names, per-channel start)"
out=$("$BIN" optimize "$BOX" 2>&1) && fail "optimize without --param succeeded"
echo "$out" | grep -q "is a Mitsuba scene: name what to recover with --param" || fail "message without --param: $out"
"$BIN" optimize -D res=16 -D max_depth=3 --param red.reflectance.value=0.3,0.2,0.1 "$BOX" --steps 2 -o "$WORK/opt" > "$WORK/opt.log" 2>&1 ||
  { cat "$WORK/opt.log"; fail "optimize with --param"; }
grep -q '"red.reflectance.value"' "$WORK/opt/parameters.json" || fail "parameters.json names the parameter as given"
out=$("$BIN" optimize "$BOX" -D res=16 --param red.sparkle.value --steps 1 -o "$WORK/opt2" 2>&1) && fail "unknown property accepted"
echo "$out" | grep -q "property 'sparkle' has no invr parameter" || fail "unknown property message: $out"

printf '{"mitsuba": {"path": "%s"}}\n' "$BOX" > "$WORK/names_the_scene.json"
"$BIN" optimize "$WORK/names_the_scene.json" -D res=16 -D max_depth=3 --param red.reflectance.value --steps 1 -o "$WORK/opt3" > "$WORK/opt3.log" 2>&1 ||
  { cat "$WORK/opt3.log"; fail "a job file naming the scene, with --param"; }
grep -q "method pt" "$WORK/opt3.log" || fail "the scene's depth makes the method pt"

echo "-- plan and the embedded service take XML scenes and jobs that name them"
"$BIN" plan "$BOX" -D res=16 --param red.reflectance.value | grep -qi "materials\|red.reflectance.value" || fail "plan"
"$BIN" run "$ROOT/docs/examples/mitsuba/cornell-optimize.json" -D res=16 --steps 2 --target-spp 4 -o "$WORK/run" > "$WORK/run.log" 2>&1 ||
  { cat "$WORK/run.log"; fail "run a job naming an XML scene"; }
test -s "$WORK/run/parameters.json" || fail "run wrote no parameters"

echo "-- bad files: exit 1, file:line: <element>"
check_bad() {  # name, xml, expected message part
  printf '%b' "$2" > "$WORK/$1.xml"
  set +e
  msg=$("$BIN" render --scene "$WORK/$1.xml" -o "$WORK/x.png" 2>&1)
  code=$?
  set -e
  [ "$code" -eq 1 ] || fail "$1: exit $code (want 1): $msg"
  echo "$msg" | grep -qF "$3" || fail "$1: '$msg' lacks '$3'"
}
HEAD='<scene version="3.0.0">\n<sensor type="perspective"><float name="fov" value="45"/></sensor>\n<emitter type="constant"/>\n'
check_bad unknown_plugin "$HEAD<shape type=\"hair\"/>\n</scene>\n" 'unknown_plugin.xml:4: <shape type="hair">: shape type'
check_bad missing_file "$HEAD\n<shape type=\"ply\"><string name=\"filename\" value=\"gone.ply\"/></shape>\n</scene>\n" "missing_file.xml:5: <shape type=\"ply\">: file 'gone.ply' not found"
check_bad cyclic_ref "$HEAD<bsdf type=\"twosided\" id=\"a\"><ref id=\"b\"/></bsdf>\n<bsdf type=\"twosided\" id=\"b\"><ref id=\"a\"/></bsdf>\n</scene>\n" "cycle of references"
check_bad bad_number "$HEAD<shape type=\"sphere\"><float name=\"radius\" value=\"1.0.0\"/></shape>\n</scene>\n" "bad_number.xml:4: <float name=\"radius\">: malformed number '1.0.0'"
check_bad wrong_version '<scene version="0.5.0">\n</scene>\n' 'wrong_version.xml:1: <scene>: version "0.5.0"'
check_bad malformed '<scene version="3.0.0">\n<shape type="cube">\n</scene>\n' "malformed.xml:3: malformed XML"
echo "mitsuba_import.sh: all checks passed"
