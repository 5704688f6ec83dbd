"""Texture recovery from Python: the painting of the `oxalis` zoo scene (a 64 x 64 albedo texture
under the shadows of a plant), recovered with ReSTIR gradients on an embedded server with local
workers. Run from the repository after `bash deploy/build.sh`:

    PYTHONPATH=build/python /usr/bin/python3 docs/examples/python/texture.py [--steps N] [--out DIR] [--target-spp N] [--final-spp N]
"""

import argparse

import numpy as np

import invr


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--out", default="out/python-texture")
    ap.add_argument("--target-spp", type=int, help="samples per pixel of the target renders (default: the job's)")
    ap.add_argument("--final-spp", type=int, help="samples per pixel of the initial and final renders (default 64)")
    a = ap.parse_args()

    def show(e):
        if e.kind == "step" and (e.step % 20 == 0 or e.step == e.steps):
            print(f"step {e.step}/{e.steps}  image loss {e.image_loss:.4g}  parameter error {e.param_error:.4g}", flush=True)

    result = invr.run("oxalis", steps=a.steps, out=a.out, on_event=show, target_spp=a.target_spp, final_spp=a.final_spp)
    texture = result.parameters["materials/painting/albedo"]  # H x W x 3
    print(f"painting texture {texture.shape}, mean {np.round(texture.reshape(-1, 3).mean(axis=0), 3)}")
    c = result.convergence
    print(f"done: parameter error {c['param_error'][0]:.4g} -> {c['param_error'][-1]:.4g} in {c['seconds'][-1]:.1f} s; results in {result.dir}")


if __name__ == "__main__":
    main()
