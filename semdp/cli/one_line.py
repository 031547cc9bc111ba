"""Bad input ends a Hydra app with one line: ``<app>: <what is wrong>`` on stderr, exit status 1,
no traceback, and nothing left behind in the output directory Hydra made for the run.

Hydra prints a composition error (an unknown option, key or override) over several lines with
a hint about ``HYDRA_FULL_ERROR``; :func:`run_app` asks Hydra to raise instead
(``HYDRA_FULL_ERROR=1`` inside the call) and reports the error in one line. A user who sets
``HYDRA_FULL_ERROR=1`` gets Hydra's full traceback, as Hydra documents.
"""

from __future__ import annotations

import os
import re
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

#: What Hydra and the apps write into a run directory before any work is done: the composed
#: config (``.hydra/``), the job's log, and the apps' own records of a run that never started.
_SET_UP_FILES = (".hydra", "config.yaml", "metrics.json", "error.txt")

_started = time.time()
_traceback_wanted = False
_inside = False


def traceback_wanted() -> bool:
    """Whether the user set ``HYDRA_FULL_ERROR=1``: then the apps let exceptions out whole."""
    return _traceback_wanted if _inside else os.environ.get("HYDRA_FULL_ERROR") == "1"


def one_line(exc: BaseException) -> str:
    """The exception's message on one line: Hydra's multi-line errors (``Could not find
    'algo/nope'`` followed by the options) joined, whitespace collapsed, the cause appended
    when the message is only Hydra's frame (``Error in call to target ...``)."""
    text = " ".join(line.strip() for line in str(exc).splitlines() if line.strip())
    text = re.sub(r"\s+", " ", text).split(" Config search path:")[0] or type(exc).__name__
    cause = exc.__cause__
    if cause is not None and str(cause).strip() and str(cause).strip() not in text:
        text += f" ({one_line(cause)})"
    return text


def run_app(app: Callable[[], Any], prog: str) -> None:
    """Call a ``@hydra.main`` function; any exception it lets out (Hydra's composition errors
    included) ends the program with ``prog: <one line>`` and exit status 1."""
    global _traceback_wanted, _inside
    full = os.environ.get("HYDRA_FULL_ERROR") == "1"
    _traceback_wanted, _inside = full, True
    os.environ["HYDRA_FULL_ERROR"] = "1"
    try:
        app()
    except Exception as exc:
        if full:
            raise
        raise SystemExit(f"{prog}: {one_line(exc)}") from None
    finally:
        _inside = False
        if not full:
            os.environ.pop("HYDRA_FULL_ERROR", None)


def discard_set_up(output_dir: str | Path, log_name: str) -> None:
    """Remove what this process wrote into ``output_dir`` before its work began (Hydra's
    ``.hydra/`` and ``<log_name>``, the app's ``config.yaml``, ``metrics.json`` and
    ``error.txt``), then the directory and its parents below the working directory if that
    leaves them empty. Files older than this process are never touched, nor is anything else."""
    output_dir = Path(output_dir).resolve()
    for name in (*_SET_UP_FILES, log_name):
        path = output_dir / name
        try:
            if path.stat().st_mtime < _started - 1.0:
                continue
        except FileNotFoundError:
            continue
        if path.is_dir():
            shutil.rmtree(path)
        else:
            path.unlink()
    cwd = Path.cwd().resolve()
    folder = output_dir
    while folder == output_dir or (folder != cwd and cwd in folder.parents):
        try:
            folder.rmdir()  # only when empty
        except OSError:
            break
        folder = folder.parent
