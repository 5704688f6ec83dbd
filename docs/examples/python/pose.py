"""A shape's pose from one image: the `pose` zoo job (a box held above a floor; its translation
and rotation are recovered from a single view), through a server the script starts itself, with
the progress events' parameter values printed as they change. Run from the repository after
`bash deploy/build.sh`:

    PYTHONPATH=build/python /usr/bin/python3 docs/examples/python/pose.py [--steps N] [--out DIR] [--target-spp N] [--final-spp N]
"""

import argparse

import invr


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--out", default="out/python-pose")
    ap.add_argument("--target-spp", type=int, help="samples per pixel of the target renders (default: the job's)")
    ap.add_argument("--final-spp", type=int, help="samples per pixel of the initial and final renders (default 64)")
    a = ap.parse_args()
    names = [p["name"] for p in invr.parameters("pose") if p["name"].startswith("shapes/")]
    print(f"the pose scene has {len(names)} shape parameters, e.g. {', '.join(names[:4])}")

    def show(e):
        if e.kind == "step" and (e.step % 25 == 0 or e.step == e.steps):
            values = "  ".join(f"{k} {[round(v, 3) for v in vs]}" for k, vs in e.parameters.items())
            print(f"step {e.step}/{e.steps}  parameter error {e.param_error:.4g}  {values}", flush=True)

    result = invr.run("pose", steps=a.steps, out=a.out, on_event=show, target_spp=a.target_spp, final_spp=a.final_spp)
    c = result.convergence
    print(f"done: parameter error {c['param_error'][0]:.4g} -> {c['param_error'][-1]:.4g}; results in {result.dir}")


if __name__ == "__main__":
    main()
