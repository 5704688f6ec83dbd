#!/usr/bin/env python3
"""The layering check on a tree made for it: the real order of docs/architecture.md, one file in
core/math that includes one in core/render (a room above it). The check must fail on that single
upward include (exit 1, counted), and pass once it is gone.

usage: check_layers_test.py CHECK_LAYERS_PY ARCHITECTURE_MD
"""
import os
import subprocess
import sys
import tempfile


def run(check, repo):
    p = subprocess.run([sys.executable, check, repo], capture_output=True, text=True)
    return p.returncode, p.stdout + p.stderr


def main():
    check, architecture = sys.argv[1], sys.argv[2]
    with tempfile.TemporaryDirectory() as repo:
        os.makedirs(os.path.join(repo, "docs"))
        with open(architecture, encoding="utf-8") as f, open(os.path.join(repo, "docs", "architecture.md"), "w") as g:
            g.write(f.read())
        for room in ("core/math", "core/render"):
            os.makedirs(os.path.join(repo, room))
        with open(os.path.join(repo, "core/render/walk.h"), "w") as f:
            f.write('#pragma once\n#include "core/math/vec.h"\n')
        with open(os.path.join(repo, "core/math/vec.h"), "w") as f:
            f.write('#pragma once\n#include "core/render/walk.h"\n')
        code, out = run(check, repo)
        counted = "1 pointing up or sideways" in out
        print(f"upward include: exit {code}, {'1 pointing up or sideways' if counted else 'not counted'}")
        print(out.strip())
        if code != 1 or not counted:
            return 1
        with open(os.path.join(repo, "core/math/vec.h"), "w") as f:
            f.write("#pragma once\n")
        code, out = run(check, repo)
        print(f"clean tree: exit {code}")
        print(out.strip())
        return 0 if code == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
