"""The ``crowdweave`` sub-commands: one module each, exposing ``configure(parser)`` and
``run(args) -> int`` (see :mod:`authoring.cli`)."""


class CLIError(Exception):
    """A user-facing error: printed without a traceback, exit code 2."""


__all__ = ["CLIError"]
