"""The errors the package raises; each says what is wrong in the user's words."""


class InvrError(Exception):
    """Anything invr reports as an error. `code`: the gRPC status name of the failure
    ("INVALID_ARGUMENT", "UNAVAILABLE", ...; None when there is none); `exit_code`: the exit
    status of the invr executable it came from (invr.run, invr.parameters, invr.export), else None."""

    def __init__(self, message, code=None, exit_code=None):
        super().__init__(message)
        self.code = code
        self.exit_code = exit_code


class InputError(InvrError):
    """The job, a file it names, a parameter name or a value is wrong (nothing was run)."""


class ServerUnavailable(InvrError):
    """No invr-server answers at the address (or it went away for longer than the reconnect budget)."""


class JobFailed(InvrError):
    """The job ended FAILED; `status` holds its final status (reason, step)."""

    def __init__(self, message, status=None):
        super().__init__(message)
        self.status = status


class JobCancelled(JobFailed):
    """The job ended CANCELLED."""
