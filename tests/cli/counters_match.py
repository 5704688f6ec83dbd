#!/usr/bin/env python3
"""A job's statistics are the same whether it runs in process (`invr optimize`) or through the
service (`invr run`: an embedded server and local workers): every column of convergence.csv but
the timings, step by step. Jobs: pose (ReSTIR with edge reservoirs, kd-trees, every boundary term
it has), rings (a variance-aware job: variance term, cost, drops), and backlit with pixel
mini-batches over several shards (pixels traced, reservoirs carried).

usage: counters_match.py BIN_DIR WORK_DIR
"""
import csv
import json
import os
import shutil
import subprocess
import sys

BIN, WORK = sys.argv[1], sys.argv[2]
os.makedirs(WORK, exist_ok=True)


def job(name, edit):
    spec = json.loads(subprocess.check_output([os.path.join(BIN, "invr"), "example", name]))
    o = spec.setdefault("optimization", {})
    o["steps"] = 3
    o["target_spp"] = 4
    edit(o)
    path = os.path.join(WORK, name + ".json")
    with open(path, "w") as f:
        json.dump(spec, f)
    return path


def rows(folder):
    with open(os.path.join(folder, "convergence.csv")) as f:
        return list(csv.DictReader(f))


def timing(column):
    return "seconds" in column


def burn_in_two(o):
    o.setdefault("restir", {})["burn_in"] = 2


def minibatch(o):
    o["pixel_sampler"] = "uniform"
    o["views_per_step"] = 6
    o["method"] = "METHOD_RESTIR"


failures = 0
for name, edit, must_have in [("pose", burn_in_two, ["boundary.primary.samples", "boundary.area_shadows_edge_first.counters.edge_reservoirs"]),
                              ("rings", lambda o: None, ["variance_term", "cost", "drops.variance"]),
                              ("backlit", minibatch, ["pixels_traced", "reservoirs_carried", "kd_trees_built"])]:
    path = job(name, edit)
    local, service, store = (os.path.join(WORK, name + s) for s in ("_optimize", "_run", "_store"))
    for d in (local, service, store):  # a kept store would hand back an earlier run's results
        shutil.rmtree(d, ignore_errors=True)
    subprocess.run([os.path.join(BIN, "invr"), "optimize", path, "--final-spp", "1", "-o", local], check=True, stdout=subprocess.DEVNULL)
    subprocess.run([os.path.join(BIN, "invr"), "run", path, "--final-spp", "1", "-o", service, "--store", store], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    a, b = rows(local), rows(service)
    if len(a) != len(b) or not a:
        print(f"{name}: {len(a)} steps in process, {len(b)} through the service")
        failures += 1
        continue
    columns = [c for c in a[0].keys() if not timing(c)]
    if set(columns) != set(c for c in b[0].keys() if not timing(c)):
        print(f"{name}: the two CSVs have different columns:", sorted(set(a[0].keys()) ^ set(b[0].keys())))
        failures += 1
        continue
    for c in must_have:
        if c not in columns:
            print(f"{name}: no column {c}")
            failures += 1
    compared = 0
    for ra, rb in zip(a, b):
        for c in columns:
            compared += 1
            if ra[c] != rb[c]:
                print(f"{name} step {ra['step']}: {c} is {ra[c]} in process, {rb[c]} through the service")
                failures += 1
    print(f"{name}: {len(a)} steps, {len(columns)} columns each ({compared} values) compared")
print("counters match" if failures == 0 else f"{failures} mismatches")
sys.exit(1 if failures else 0)
