"""A job argument as a ResolveJob request: what the server needs to resolve it (zoo name, job
JSON, Mitsuba scene) and the folder the job's relative file names are read from when the server
asks for them. Nothing here runs an invr executable."""

import copy
import json
import os
from pathlib import Path

import numpy as np

from invr._errors import InputError
from invr.v1 import service_pb2


def override_lists(params=None, defines=None, sets=None, steps=None, method=None, target_spp=None, seed=None,
                   snapshot_every=None):
    """(params, defines, sets) as `invr`'s --param, -D and --set would carry them."""
    out_params = []
    items = params.items() if isinstance(params, dict) else (params or [])
    for p in items:
        # "name", "name=0.5", ("name", 0.5), ("name", [0.1, 0.2, 0.3]); a dict maps names to values (or None)
        if isinstance(p, (tuple, list)):
            name, value = p
            if value is None:
                out_params.append(str(name))
            else:
                values = np.ravel(np.asarray(value, dtype=float)).tolist()
                out_params.append(f"{name}=" + ",".join(repr(float(v)) for v in values))
        else:
            out_params.append(str(p))
    out_defines = [f"{k}={v}" for k, v in (defines or {}).items()]
    all_sets = dict(sets or {})
    if steps is not None:
        all_sets["optimization.steps"] = int(steps)
    if method is not None:
        all_sets["optimization.method"] = method
    if target_spp is not None:
        all_sets["optimization.target_spp"] = int(target_spp)
    if seed is not None:
        all_sets["optimization.seed"] = int(seed)
    if snapshot_every is not None:
        all_sets["optimization.snapshot_every"] = int(snapshot_every)
    out_sets = [f"{k}={v if isinstance(v, str) else json.dumps(v)}" for k, v in all_sets.items()]
    return out_params, out_defines, out_sets


def _absolute_by_content(node, upload):
    """AssetRef objects ({"path": ...}) with an absolute path, uploaded and named by content
    instead: the server reads no file of this machine. Returns whether any changed."""
    changed = False
    if isinstance(node, dict):
        for k, v in node.items():
            if isinstance(v, dict) and set(v.keys()) == {"path"} and isinstance(v["path"], str) and k != "mitsuba":
                if os.path.isabs(v["path"]):
                    node[k] = {"sha256": upload(v["path"])}
                    changed = True
            else:
                changed = _absolute_by_content(v, upload) or changed
    elif isinstance(node, list):
        for v in node:
            changed = _absolute_by_content(v, upload) or changed
    return changed


def resolve_request(job, upload):
    """(ResolveJobRequest, base folder) for a job argument: a dict (relative paths from the working
    directory), a job file (.json), a Mitsuba 3 scene (.xml) or a zoo scene name. `upload(path)`
    returns an uploaded file's SHA-256."""
    req = service_pb2.ResolveJobRequest()
    if isinstance(job, dict):
        doc = copy.deepcopy(job)
        mitsuba = doc.get("mitsuba", {}).get("path") if isinstance(doc.get("mitsuba"), dict) else None
        if isinstance(mitsuba, str) and os.path.isabs(mitsuba):
            raise InputError(f"mitsuba.path: '{mitsuba}' is absolute: give it relative to the working directory")
        _absolute_by_content(doc, upload)
        req.job_json = json.dumps(doc)
        return req, Path.cwd()
    if not isinstance(job, (str, os.PathLike)):
        raise InputError(f"a job is a dict, a job file (.json), a Mitsuba scene (.xml) or a zoo name; got {type(job).__name__}")
    text = os.fspath(job)
    if text.endswith(".json"):
        path = Path(text)
        if not path.is_file():
            raise InputError(f"job file '{text}': not found")
        raw = path.read_text()
        try:
            doc = json.loads(raw)
        except ValueError:
            doc = None  # the server names the syntax error's line and column
        if isinstance(doc, dict) and _absolute_by_content(doc, upload):
            raw = json.dumps(doc)
        req.job_json = raw
        req.name = text  # errors name the file, as the CLI's do
        return req, path.parent
    if text.endswith(".xml"):
        path = Path(text)
        if not path.is_file():
            raise InputError(f"Mitsuba scene '{text}': not found")
        req.mitsuba_xml = path.name
        req.files[path.name] = upload(path)
        return req, path.parent
    if isinstance(job, os.PathLike):
        raise InputError(f"'{text}': a job file ends in .json, a Mitsuba scene in .xml")
    req.zoo = text
    return req, Path.cwd()
