"""The one error type that malformed input raises."""

from __future__ import annotations


class SeriesFormatError(ValueError):
    """A test series breaks the format; the message names the file, the field or row, and the fault.

    Attributes
    ----------
    path : str
        The file (manifest or CSV) where the fault was found.
    where : str
        The field (``tests[2].frequency_hz``), column (``F``) or row (``row 17``).
    problem : str
        What is wrong, in words.
    """

    def __init__(self, path, where: str, problem: str):
        self.path = str(path)
        self.where = where
        self.problem = problem
        location = f"{self.path}: {where}" if where else self.path
        super().__init__(f"{location}: {problem}")
