#!/usr/bin/env python3
"""The layering test: every #include "..." in core/, proto/wire/, server/, worker/ and client/ must
point at its own room or at a room on a lower level of the order that docs/architecture.md gives
(the fenced block marked `layers`). Rooms on one level must not include each other. There are no
exceptions: a file that needs something above it means a type sits on the wrong level.

usage: check_layers.py [REPO]   (exit 0: clean; 1: violations, each printed as file:line)
"""
import os
import re
import sys


def read_layers(repo):
    text = open(os.path.join(repo, "docs", "architecture.md"), encoding="utf-8").read()
    m = re.search(r"```layers\n(.*?)```", text, re.S)
    if not m:
        sys.exit("docs/architecture.md has no ```layers block")
    level = {}
    for n, line in enumerate(l for l in m.group(1).splitlines() if l.strip() and not l.lstrip().startswith("#")):
        for room in line.split("#")[0].split():
            if room in level:
                sys.exit(f"docs/architecture.md: room {room} is listed twice")
            level[room] = n
    return level


def room_of(path, level):
    """The deepest listed room that holds `path` (a repository path or an include path)."""
    if path.startswith("invr/v1/"):
        return "proto"  # generated from proto/invr/v1/*.proto
    parts = path.split("/")[:-1]
    while parts:
        r = "/".join(parts)
        if r in level:
            return r
        parts.pop()
    return None


def main():
    repo = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", ".."))
    level = read_layers(repo)
    include = re.compile(r'^\s*#\s*include\s+"([^"]+)"')
    problems, files, edges = [], 0, 0
    for top in ("core", "proto/wire", "server", "worker", "client"):
        for dirpath, _, names in os.walk(os.path.join(repo, top)):
            for name in sorted(names):
                if not name.endswith((".h", ".cc")):
                    continue
                rel = os.path.relpath(os.path.join(dirpath, name), repo)
                src = room_of(rel, level)
                files += 1
                if src is None:
                    problems.append(f"{rel}: in no room of docs/architecture.md's layers")
                    continue
                for n, line in enumerate(open(os.path.join(dirpath, name), encoding="utf-8"), 1):
                    m = include.match(line)
                    if not m:
                        continue
                    dst = room_of(m.group(1), level)
                    edges += 1
                    if dst is None:
                        problems.append(f'{rel}:{n}: #include "{m.group(1)}" is in no room of the layers')
                    elif dst != src and level[dst] >= level[src]:
                        how = "the same level as" if level[dst] == level[src] else "above"
                        problems.append(f'{rel}:{n}: #include "{m.group(1)}": {dst} is {how} {src}')
    for p in problems:
        print(p)
    print(f"layering: {files} files, {edges} includes, {len(problems)} pointing up or sideways")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
