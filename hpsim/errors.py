"""User-facing errors: the CLI prints these as one line and exits with code 2."""


class UserInputError(ValueError):
    """Bad input from a user (argument, parameter file, scenario, data file).

    The message must name where the problem is (file, key path or argument), the
    offending value and what is allowed. The CLI prints it without a traceback.
    """


class SimulationError(RuntimeError):
    """A simulation could not go on (e.g. a strut bottomed out, the solver failed).

    The message says where (distance, strut, state). Whatever was already written
    stays on disk.
    """


class Terminated(BaseException):
    """SIGTERM (kill PID, a scheduler's time limit) turned into an exception by the CLI, so that what a command
    started (compilers, worker processes) is stopped and open files are closed on the way out (exit code 143)."""
