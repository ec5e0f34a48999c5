"""The one exception the command line turns into a one-line message and exit code 2."""


class WorkbenchError(Exception):
    """Bad input or an environment problem the user can fix; never a bug."""


def require(condition: bool, message: str) -> None:
    """Raise :class:`WorkbenchError` with ``message`` unless ``condition`` holds."""
    if not condition:
        raise WorkbenchError(message)


class DataNotFound(WorkbenchError):
    """Real data that is not where it was looked for: the demo skips a scenario for this
    reason alone; every other error fails it."""


class DataWarning(UserWarning):
    """Real data that needed a repair to be read (rows put back in time order, a truncated last
    line left out, repeated time stamps): the command line prints one line for each, the
    metrics count them."""
