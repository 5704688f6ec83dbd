"""invr from Python: submit inverse-rendering jobs to an invr-server, watch them, read their results.

    import invr
    result = invr.run("cornell", steps=50)                 # embedded server + local workers
    print(result.parameters["materials/red/albedo"])

    client = invr.Client()                                  # $INVR_SERVER, else 127.0.0.1:50051
    job = client.submit("job.json", steps=200)
    for event in job.watch():
        if event.kind == "step":
            print(event.step, event.loss, event.image_loss)
    result = job.result("out/")

docs/python.md documents the package.
"""

from invr._errors import InvrError, InputError, ServerUnavailable, JobFailed, JobCancelled
from invr._client import Client, Job, DEFAULT_ADDRESS
from invr._events import Event
from invr._results import Result, read_results, read_image, read_ply
from invr._local import run, parameters, export, binary

__all__ = [
    "Client", "Job", "Event", "Result", "run", "parameters", "export", "read_results", "read_image", "read_ply", "binary",
    "InvrError", "InputError", "ServerUnavailable", "JobFailed", "JobCancelled", "DEFAULT_ADDRESS",
]

try:
    from invr._version import __version__  # written by the build
except ImportError:  # pragma: no cover - a source checkout without a build
    __version__ = "unknown"
