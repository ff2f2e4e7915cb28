"""All-or-nothing output: folders and JSON files appear complete or not at all.

Readers (the CLI, a notebook, a second run) may look at an output path at any moment, and a
run can be interrupted at any moment. Everything is therefore written under a temporary
sibling name on the same file system and renamed into place at the end, which is atomic.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

import numpy as np


class OutputExistsError(FileExistsError):
    """The output path is already taken and the caller did not ask to replace it.

    Parameters
    ----------
    path : str or Path
        The path that already exists.
    hint : str, optional
        How to get past the refusal, appended to the message.
    """

    def __init__(self, path, hint: str = "pass overwrite=True to replace it"):
        super().__init__(errno.EEXIST, "already exists", str(path))
        self.hint = hint

    def __str__(self) -> str:
        return f"{self.filename} already exists; {self.hint}"


def _remove(path: Path) -> None:
    # A replaced target may be a folder or a stray file; both must go.
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        try:
            path.unlink()
        except FileNotFoundError:
            pass


def _sibling(path: Path, tag: str) -> Path:
    # Hidden and on the same file system as the target, so that the final rename is atomic
    # and an interrupted run leaves nothing that looks like real output.
    return Path(tempfile.mkdtemp(prefix=f".{path.name}.{tag}-", dir=path.parent))


def _move_into_place(tmp: Path, path: Path, overwrite: bool) -> None:
    if not os.path.lexists(path):
        try:
            os.rename(tmp, path)
            return
        except OSError as exc:
            # Someone created the target between our check and our rename.
            if not os.path.lexists(path):
                raise
            if not overwrite:
                raise OutputExistsError(path) from exc
    elif not overwrite:
        raise OutputExistsError(path)
    # rename() cannot replace a non-empty folder, so the old one is moved aside first;
    # the target is briefly absent but never half-written.
    trash_dir = _sibling(path, "old")
    trash = trash_dir / "old"
    os.rename(path, trash)
    try:
        os.rename(tmp, path)
    except BaseException:
        os.rename(trash, path)
        _remove(trash_dir)
        raise
    _remove(trash_dir)


@contextmanager
def atomic_output_dir(path, overwrite: bool = False) -> Iterator[Path]:
    """Build a folder under a temporary name and move it to `path` only if the block succeeds.

    Parameters
    ----------
    path : str or Path
        Final location of the folder. Its parent is created if needed.
    overwrite : bool, default False
        Replace an existing `path`. The old content is removed only after the new folder is
        complete; without this flag an existing `path` is refused before anything is written.

    Yields
    ------
    Path
        An empty temporary folder next to `path`; write the output into it.

    Raises
    ------
    OutputExistsError
        `path` exists and `overwrite` is False.

    Notes
    -----
    If the block raises (or is interrupted), the temporary folder is deleted and `path` is
    left as it was.
    """
    path = Path(path)
    if os.path.lexists(path) and not overwrite:
        raise OutputExistsError(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _sibling(path, "tmp")
    try:
        # mkdtemp makes the folder private (0700); output is meant to be shared like any other.
        os.chmod(tmp, 0o755)
        yield tmp
        _move_into_place(tmp, path, overwrite)
    except BaseException:
        _remove(tmp)
        raise


def to_jsonable(obj: Any) -> Any:
    """`json` fallback for the numpy scalars and arrays that end up in manifests and summaries."""
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON serializable")


def _finite_or_null(obj: Any) -> Any:
    """obj with every NaN or infinite float (numpy's included) replaced by None."""
    if isinstance(obj, dict):
        return {key: _finite_or_null(value) for key, value in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite_or_null(value) for value in obj]
    if isinstance(obj, np.ndarray):
        return _finite_or_null(obj.tolist())
    if isinstance(obj, (float, np.floating)):
        return float(obj) if np.isfinite(obj) else None
    return obj


def dumps(obj: Any, *, non_finite_as_null: bool = True) -> str:
    """Serialize `obj` the way every JSON file of the package is written (indented, strict
    JSON). A NaN or infinite value, one the computation could not give, is written as null;
    with non_finite_as_null=False it raises ValueError instead (a series manifest, whose fields
    must hold numbers)."""
    # NaN and Infinity are not JSON, and a reader would choke on them; refusing them in results
    # threw away a whole diagnosis over one flat loop's infinite roll-off, so they become null
    content = _finite_or_null(obj) if non_finite_as_null else obj
    return json.dumps(content, indent=2, allow_nan=False, default=to_jsonable) + "\n"


def write_json_atomic(path, obj: Any) -> Path:
    """Write `obj` as JSON to `path` so that readers see the old file or the new one, never a part.

    Parameters
    ----------
    path : str or Path
        Destination file; an existing file is replaced.
    obj : object
        JSON-serializable data; numpy scalars and arrays are converted.

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    TypeError, ValueError
        `obj` cannot be serialized (nothing is written then).
    """
    path = Path(path)
    text = dumps(obj)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.tmp-", dir=path.parent)
    try:
        # mkstemp makes the file private (0600); give it the usual permissions of a result.
        os.chmod(tmp, 0o644)
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return path
