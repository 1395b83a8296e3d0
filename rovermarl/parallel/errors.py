"""The backends' one error type, in a module of its own so that no backend imports its package back."""


class BackendError(Exception):
    """Ray failed under a job (a dead GCS, raylet or actor past its retries, or no chunk finished within
    ``parallel.stall_timeout``); ``str(err)`` is one line naming the cause."""
