"""Errors raised by the solvers."""

__all__ = ["ConvergenceError"]


class ConvergenceError(RuntimeError):
    """A solve could not go on; the message names time, step and the worst location."""
