"""The service from Python: Client (one channel to an invr-server) and Job (one submitted job)."""

import os
import sys
import time
import uuid
from pathlib import Path

import grpc
from google.protobuf import json_format
from google.protobuf.descriptor import FieldDescriptor

from invr._constants import MAX_MESSAGE_BYTES, CHUNK_BYTES
from invr._errors import InvrError, InputError, ServerUnavailable, JobFailed, JobCancelled
from invr._events import Event, to_python

try:
    from invr.v1 import job_pb2, service_pb2, service_pb2_grpc
except ImportError as e:  # pragma: no cover - the build generates them
    raise ImportError("invr's generated gRPC modules are missing: install the package (pip install ./client/python) or use "
                      "the one the build assembles in build/python (PYTHONPATH=build/python)") from e

DEFAULT_ADDRESS = "127.0.0.1:50051"
_MAX_MESSAGE = MAX_MESSAGE_BYTES  # generated from proto/wire/wire.h
_CHUNK = CHUNK_BYTES
_FINISHED = ("SUCCEEDED", "FAILED", "CANCELLED")


def _read(path, what):
    try:
        return Path(path).read_bytes()
    except OSError as e:
        raise InputError(f"{what}: cannot read '{path}': {e.strerror}") from None


class Client:
    """A connection to an invr-server.

    address: host:port (default $INVR_SERVER, else 127.0.0.1:50051); token (or token_file, or
    $INVR_TOKEN): the server's client token; tls_ca: the CA certificate (PEM file) that signed the
    server's, for TLS; tls_cert/tls_key: a client certificate for mutual TLS; tls_server_name: the
    name in the server's certificate when it is not the address's host.
    """

    def __init__(self, address=None, token=None, tls_ca=None, tls_cert=None, tls_key=None, tls_server_name=None,
                 token_file=None, reconnect_seconds=60.0):
        self.address = address or os.environ.get("INVR_SERVER") or DEFAULT_ADDRESS
        if token is None and token_file is not None:
            token = _read(token_file, "token_file").decode().strip()
        if token is None:
            token = os.environ.get("INVR_TOKEN") or None
        self._metadata = (("authorization", "Bearer " + token),) if token else ()
        self.reconnect_seconds = reconnect_seconds
        self._uploaded = {}
        options = [("grpc.max_receive_message_length", _MAX_MESSAGE), ("grpc.max_send_message_length", _MAX_MESSAGE),
                   ("grpc.initial_reconnect_backoff_ms", 100), ("grpc.max_reconnect_backoff_ms", 1000),
                   # gRPC reads this as the time one connection attempt (with its TLS handshake) may
                   # take, not as a back-off: 100 ms timed out handshakes with a loaded server.
                   ("grpc.min_reconnect_backoff_ms", 20000)]
        if tls_ca is not None:
            creds = grpc.ssl_channel_credentials(
                root_certificates=_read(tls_ca, "tls_ca"),
                private_key=_read(tls_key, "tls_key") if tls_key else None,
                certificate_chain=_read(tls_cert, "tls_cert") if tls_cert else None)
            if tls_server_name:
                options.append(("grpc.ssl_target_name_override", tls_server_name))
            self._open = lambda: grpc.secure_channel(self.address, creds, options=options)
        else:
            if tls_cert or tls_key:
                raise InputError("tls_cert and tls_key need tls_ca (the CA that signed the server's certificate)")
            self._open = lambda: grpc.insecure_channel(self.address, options=options)
        self._channel = self._open()
        self._stub = service_pb2_grpc.InvrServiceStub(self._channel)

    def _reconnect(self, timeout):
        """A fresh channel once the server answers again (after a restart). A new stream on the
        old channel can stall in grpcio 1.51 when the server came back while it was reconnecting."""
        self._channel.close()
        self._channel = self._open()
        self._stub = service_pb2_grpc.InvrServiceStub(self._channel)
        try:
            grpc.channel_ready_future(self._channel).result(timeout=max(0.1, timeout))
            return True
        except grpc.FutureTimeoutError:
            return False

    # -- plumbing

    def close(self):
        self._channel.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _call(self, method, request, what, timeout=60):
        try:
            return method(request, metadata=self._metadata, timeout=timeout)
        except grpc.RpcError as e:
            raise self._error(e, what) from None

    def _error(self, e, what):
        code = e.code() if hasattr(e, "code") else None
        details = e.details() if hasattr(e, "details") else str(e)
        name = code.name if code is not None else "UNKNOWN"
        if code in (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.DEADLINE_EXCEEDED):
            return ServerUnavailable(f"{what}: no invr-server answers at {self.address} ({details})", name)
        if code in (grpc.StatusCode.INVALID_ARGUMENT, grpc.StatusCode.NOT_FOUND, grpc.StatusCode.RESOURCE_EXHAUSTED,
                    grpc.StatusCode.FAILED_PRECONDITION):
            return InputError(f"{what}: {details}", name)
        if code in (grpc.StatusCode.UNAUTHENTICATED, grpc.StatusCode.PERMISSION_DENIED):
            return InvrError(f"{what}: the server refused the credentials ({details}); pass token= or set $INVR_TOKEN", name)
        return InvrError(f"{what}: {details} ({name})", name)

    # -- jobs

    def spec(self, job, params=None, defines=None, sets=None, steps=None, method=None, target_spp=None, seed=None,
             snapshot_every=None, for_optimization=True):
        """The JobSpec message a job argument means (see submit), resolved by the server
        (ResolveJob, with the code `invr` runs locally): the files the job or its Mitsuba scene
        names are uploaded on the way, so the spec names every file by its SHA-256. Needs no invr
        build on this machine. for_optimization: the job must name parameters (submit, plan)."""
        from invr._resolve import resolve_request, override_lists
        p, d, s = override_lists(params=params, defines=defines, sets=sets, steps=steps, method=method, target_spp=target_spp,
                                 seed=seed, snapshot_every=snapshot_every)
        req, base = resolve_request(job, self.upload)
        req.params.extend(p)
        req.defines.extend(d)
        req.sets.extend(s)
        req.for_optimization = bool(for_optimization)
        for _ in range(64):  # a Mitsuba <include> names its files only once it is there
            resp = self._call(self._stub.ResolveJob, req, "job")
            for w in resp.warnings:
                sys.stderr.write(f"warning: {w}\n")
            if not resp.missing_files:
                return resp.spec
            for name in resp.missing_files:
                if name in req.files:
                    raise InvrError(f"the server asks again for '{name}', which was uploaded")
                f = base / name
                if not f.is_file():
                    raise InputError(f"the job names '{name}', which is not at '{f}'")
                req.files[name] = self.upload(f)
        raise InvrError("the job's files were still incomplete after 64 rounds of uploads")

    def upload(self, path):
        """Uploads a file to the server's asset store; returns its SHA-256 (lowercase hex)."""
        path = Path(path)
        if not path.is_file():
            raise InputError(f"asset '{path}' not found")
        st = path.stat()
        key = (str(path.resolve()), st.st_size, st.st_mtime_ns)
        if key in self._uploaded:  # a job's files once per client, however often it is resolved
            return self._uploaded[key]

        def chunks():
            with open(path, "rb") as f:
                while True:
                    b = f.read(_CHUNK)
                    if not b:
                        break
                    yield service_pb2.AssetChunk(data=b)

        sha = self._call(self._stub.UploadAsset, chunks(), f"upload {path}", timeout=None).sha256
        self._uploaded[key] = sha
        return sha

    def _upload_assets(self, message, where=""):
        """Every AssetRef with a path, uploaded and replaced by its SHA-256 (as the CLI does)."""
        for field, value in message.ListFields():
            items = value if field.label == FieldDescriptor.LABEL_REPEATED else [value]
            if field.type != FieldDescriptor.TYPE_MESSAGE:
                continue
            if field.message_type.GetOptions().map_entry:
                items = [v for v in value.values()] if field.message_type.fields_by_name["value"].message_type else []
            for item in items:
                if item.DESCRIPTOR.full_name == "invr.v1.AssetRef":
                    if item.WhichOneof("source") == "path":
                        item.sha256 = self.upload(item.path)
                else:
                    self._upload_assets(item, where)

    def submit(self, job, params=None, defines=None, sets=None, steps=None, method=None, target_spp=None, seed=None,
               priority=None, max_workers=None, request_id=None, snapshot_every=None):
        """Submits a job and returns its Job. `job`: a dict (relative paths from the working
        directory), a job file (.json), a Mitsuba 3 scene (.xml; name what to recover with params)
        or a zoo scene name. params: names (or name -> start values) that replace the job's
        parameter list; defines: a Mitsuba scene's <default> overrides; sets: job field path ->
        value (like --set); steps, method ("pt", "ris", "restir"), target_spp, seed, snapshot_every:
        shorthands (snapshot_every=N: renders and parameters every N steps, Result.snapshots)."""
        spec = self.spec(job, params=params, defines=defines, sets=sets, steps=steps, method=method, target_spp=target_spp,
                         seed=seed, snapshot_every=snapshot_every)
        if priority is not None:
            spec.scheduling.priority = int(priority)
        if max_workers is not None:
            spec.scheduling.max_workers = int(max_workers)
        self._upload_assets(spec)
        req = service_pb2.SubmitJobRequest(request_id=request_id or uuid.uuid4().hex, spec=spec)
        resp = self._call(self._stub.SubmitJob, req, "submit")
        return Job(self, resp.job_id)

    def job(self, job_id):
        """The Job of an id (from submit, `invr submit` or `invr list`)."""
        return Job(self, job_id)

    def jobs(self):
        """Every job the server knows, as JobStatus dicts."""
        return [to_python(j) for j in self._call(self._stub.ListJobs, service_pb2.ListJobsRequest(), "list").jobs]

    def workers(self):
        """The connected workers, as WorkerStatus dicts."""
        return [to_python(w) for w in self._call(self._stub.ListWorkers, service_pb2.ListWorkersRequest(), "workers").workers]

    def plan(self, job, **overrides):
        """What the job would compute and need on this server (JobPlan as a dict), without running it."""
        spec = self.spec(job, **overrides)
        self._upload_assets(spec)
        return to_python(self._call(self._stub.PlanJob, service_pb2.PlanJobRequest(spec=spec), "plan"))

    def parameters(self, scene, defines=None):
        """The optimisable names of a scene (zoo name, job file, Mitsuba scene or dict) as this
        server sees it (DescribeScene): a list of dicts with name, kind, size, width, height,
        channels, lower, upper, learning_rate and aliases (Mitsuba names). invr.parameters() asks
        the local invr binary instead, with no server."""
        spec = self.spec(scene, defines=defines, for_optimization=False)
        self._upload_assets(spec)
        desc = self._call(self._stub.DescribeScene, service_pb2.DescribeSceneRequest(spec=spec), "parameters")
        return [to_python(p) for p in desc.parameters]  # an infinite bound is None, as JSON's null

    def wait_for_workers(self, n=1, timeout=60.0):
        """Waits until at least n workers are connected; raises ServerUnavailable after timeout."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                if len(self.workers()) >= n:
                    return
            except ServerUnavailable:
                pass
            if time.monotonic() > deadline:
                raise ServerUnavailable(f"fewer than {n} worker(s) connected to {self.address} after {timeout} s")
            time.sleep(0.2)


class Job:
    """A job on a server: status(), watch(), cancel(), wait(), result()."""

    def __init__(self, client, job_id):
        self.client = client
        self.id = job_id

    def __repr__(self):
        return f"Job({self.id!r} on {self.client.address})"

    def status(self):
        """The JobStatus as a dict: state, step, steps, loss, param_error, seconds, results, ..."""
        return to_python(self.client._call(self.client._stub.GetJob, service_pb2.GetJobRequest(job_id=self.id), "status"))

    def cancel(self):
        """Asks the server to cancel the job (idempotent); returns its status."""
        return to_python(self.client._call(self.client._stub.CancelJob, service_pb2.CancelJobRequest(job_id=self.id), "cancel"))

    def watch(self, from_sequence=0, reconnect_seconds=None):
        """Yields the job's progress events (Event) until its final one. When the stream breaks (a
        server restart), waits up to reconnect_seconds (default: the client's, 60) for the server
        and resumes after the last event seen, as `invr watch` does."""
        budget = self.client.reconnect_seconds if reconnect_seconds is None else reconnect_seconds
        next_seq = from_sequence
        lost_since = None
        while True:
            req = service_pb2.WatchJobRequest(job_id=self.id, from_sequence=next_seq)
            try:
                for ev in self.client._stub.WatchJob(req, metadata=self.client._metadata):
                    lost_since = None
                    event = Event(to_python(ev))
                    next_seq = event.sequence + 1
                    yield event
                    if event.kind == "final":
                        return
                # The stream ended without a final event: the server is going away.
            except grpc.RpcError as e:
                if e.code() not in (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.CANCELLED, grpc.StatusCode.UNKNOWN,
                                    grpc.StatusCode.INTERNAL):
                    raise self.client._error(e, "watch") from None
            now = time.monotonic()
            if lost_since is None:
                lost_since = now
            if now - lost_since > budget or not self.client._reconnect(budget - (now - lost_since)):
                raise ServerUnavailable(f"watch {self.id}: the server at {self.client.address} did not come back within "
                                        f"{budget:g} s (the job goes on; watch again later)")

    def wait(self, timeout=None, raise_on_failure=True):
        """Blocks until the job ends and returns its final status (a dict). Raises JobFailed or
        JobCancelled when it did not succeed (unless raise_on_failure=False), TimeoutError after
        timeout seconds."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            st = self.status()
            if st["state"] in _FINISHED:
                break
            if deadline is not None and time.monotonic() > deadline:
                raise TimeoutError(f"job {self.id} still {st['state']} after {timeout} s (step {st['step']}/{st['steps']})")
            time.sleep(0.25)
        if raise_on_failure and st["state"] != "SUCCEEDED":
            cls = JobCancelled if st["state"] == "CANCELLED" else JobFailed
            raise cls(f"job {self.id} {st['state']}: {st.get('reason', '')}", st)
        return st

    def fetch(self, name, out):
        """Downloads one result file (a name from status()["results"]) into the folder out."""
        out = Path(out)
        rel = Path(os.path.normpath(name)) if name else Path(".")
        if rel.is_absolute() or not rel.parts or rel.parts[0] in ("..", "."):
            raise InputError(f"fetch: the server named a result {name!r} outside the results folder")
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        req = service_pb2.FetchResultRequest(job_id=self.id, name=name)
        tmp = out / (str(rel) + ".part")
        try:
            with open(tmp, "wb") as f:
                for chunk in self.client._stub.FetchResult(req, metadata=self.client._metadata):
                    f.write(chunk.data)
        except grpc.RpcError as e:
            tmp.unlink(missing_ok=True)
            raise self.client._error(e, f"fetch {name}") from None
        tmp.replace(out / rel)
        return out / rel

    def result(self, out=None, wait=True):
        """Downloads every result file into out (default: a new temporary folder) and returns the
        Result. Waits for the job to end first (wait=False: what is there now). A failed or
        cancelled job's result holds its last checkpoint's parameters and convergence."""
        import tempfile
        from invr._results import Result
        if wait:
            self.wait(raise_on_failure=False)
        out = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix=f"invr-{self.id}-"))
        for name in self.status()["results"]:
            self.fetch(name, out)
        return Result(out)
