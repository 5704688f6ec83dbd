"""A photograph as the target: an image on disk (here one rendered for the purpose; use your own
EXR/PNG of the same framing) and the red wall's colour of the `cornell` zoo scene to recover from
it. With a photograph the truth is unknown, so there is no parameter error: the smoothed image loss
is the convergence signal. Run from the repository after `bash deploy/build.sh`:

    PYTHONPATH=build/python /usr/bin/python3 docs/examples/python/photo.py [--steps N] [--out DIR] [--target-spp N] [--final-spp N]
"""

import argparse
import subprocess
from pathlib import Path

import invr


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--out", default="out/python-photo")
    ap.add_argument("--target-spp", type=int, default=64, help="samples per pixel of the rendered photograph")
    ap.add_argument("--final-spp", type=int, help="samples per pixel of the initial and final renders (default 64)")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    photo = out / "photo.exr"
    # The "photograph": the scene as it is (red wall (0.63, 0.065, 0.05)), 64 samples per pixel by default.
    subprocess.run([invr.binary(), "render", "--scene", "cornell", "--spp", str(a.target_spp), "-o", str(photo)], check=True, stdout=subprocess.DEVNULL)
    job = {
        "zoo": "cornell",
        "optimization": {
            "parameters": [{"name": "materials/red/albedo", "initial": 0.5, "learning_rate": 0.02}],
            "targets": [{"path": str(photo)}],
            "method": "restir",
            "loss": "relative_l2",
            "steps": a.steps,
        },
    }
    losses = []
    result = invr.run(job, out=out / "results", final_spp=a.final_spp, on_event=lambda e: e.kind == "step" and losses.append(e.image_loss))
    red = result.parameters["materials/red/albedo"]
    print(f"red wall recovered as {red.round(3)} (the photograph's: [0.63 0.065 0.05])")
    print(f"done: image loss {losses[0]:.4g} -> {losses[-1]:.4g}; results in {result.dir}")


if __name__ == "__main__":
    main()
