"""Atomic result files: JSON (``settings``, ``rows``, ...) or CSV (rows) chosen by suffix."""

from __future__ import annotations

import csv
import io
import json
import math
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

from lunarviz.errors import LunarvizError

SUFFIXES = (".json", ".csv")


def check_output_path(path, suffixes=SUFFIXES) -> Path:
    """Validate an output path before any work is done: suffix and a writable directory."""
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise LunarvizError(f"output {str(path)!r} must end in {' or '.join(suffixes)}")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise LunarvizError(f"output directory {str(parent)!r} does not exist")
    if not os.access(parent, os.W_OK):
        raise LunarvizError(f"output directory {str(parent)!r} is not writable")
    if p.exists() and p.is_dir():
        raise LunarvizError(f"output {str(path)!r} is a directory")
    return p


def json_safe(v):
    """JSON-safe values: NaN/inf become null."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {k: json_safe(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [json_safe(x) for x in v]
    if hasattr(v, "item") and not isinstance(v, (str, bytes)):
        return json_safe(v.item())
    return v


@contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path``; on success it replaces ``path`` (``os.replace``),
    on any error it is removed: the target is never left half-written."""
    p = Path(path)
    fd, tmp = tempfile.mkstemp(dir=p.parent if str(p.parent) else ".", prefix=f".{p.stem}.", suffix=p.suffix)
    os.close(fd)
    try:
        yield tmp
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; results get the usual mode
        os.replace(tmp, p)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_bytes_atomic(path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`)."""
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        fh.write(data)


def write_results(path, payload: dict) -> None:
    """Write ``payload`` (with a ``rows`` list) as JSON, or its rows as CSV, atomically."""
    p = Path(path)
    if p.suffix.lower() == ".json":
        data = json.dumps(json_safe(payload), indent=2, allow_nan=False).encode()
    else:
        rows = [json_safe(r) for r in payload.get("rows", [])]
        fields: list[str] = []
        for r in rows:
            fields += [k for k in r if k not in fields]
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in fields})
        data = buf.getvalue().encode()
    write_bytes_atomic(p, data)
