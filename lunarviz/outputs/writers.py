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
    if not isinstance(path, (str, os.PathLike)):
        raise LunarvizError(f"output {path!r} must be a path (a string), not {type(path).__name__}")
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
    """Yield a private temporary path beside ``path``; when the caller has written it, it is
    flushed to disk (``fsync``), checked to be non-empty and moved onto ``path``
    (``os.replace``, which replaces a symlink rather than following it). On any error, the
    interrupt included, the temporary file is removed: the target is never left half-written.
    A full disk or an unwritable folder is one :class:`LunarvizError` line naming the path."""
    p = Path(path)
    tmp = _temp_beside(p)
    try:
        yield tmp
        _seal(tmp, p)
        os.replace(tmp, p)
    except OSError as exc:
        _remove(tmp)
        raise LunarvizError(f"cannot write {str(path)!r}: {exc.strerror or exc}") from None
    except BaseException:
        _remove(tmp)
        raise


def _temp_beside(p: Path) -> str:
    """A new private (0600) temporary file in ``p``'s folder, named after it."""
    try:
        fd, tmp = tempfile.mkstemp(dir=p.parent if str(p.parent) else ".", prefix=f".{p.stem}.", suffix=p.suffix)
    except OSError as exc:
        raise LunarvizError(f"cannot write {str(p)!r}: {exc.strerror or exc}") from None
    os.close(fd)
    return tmp


def _seal(tmp: str, p: Path) -> None:
    """A written temporary made ready to replace ``p``: non-empty, on disk, the usual mode."""
    if os.path.getsize(tmp) == 0:
        raise LunarvizError(f"writing {str(p)!r} produced an empty file (is the disk full?)")
    _fsync(tmp)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; results get the usual mode


def _fsync(path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _remove(path) -> None:
    if os.path.lexists(path):
        os.unlink(path)


def write_bytes_atomic(path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`), checking that every byte
    reached the file."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
        if os.path.getsize(tmp) != len(data):
            raise LunarvizError(f"writing {str(path)!r} stopped after {os.path.getsize(tmp)} of {len(data)} bytes "
                                f"(is the disk full?)")


def png_bytes(img) -> bytes:
    """An RGB(A) picture (height × width × 3 or 4, uint8) as PNG bytes."""
    import numpy as np
    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(np.asarray(img)).save(buf, format="PNG")
    return buf.getvalue()


def write_picture(path, img) -> None:
    """Write a picture as PNG, atomically."""
    write_bytes_atomic(path, png_bytes(img))


def check_free_space(path, nbytes: int) -> None:
    """Refuse, before writing, a file its folder cannot hold: twice ``nbytes`` and a megabyte
    (for writers that crash the process or leave broken files on a full disk: VTK, HDF5)."""
    import shutil
    p = Path(path)
    folder = p.parent if str(p.parent) else Path(".")
    need = 2 * int(nbytes) + (1 << 20)
    free = shutil.disk_usage(folder).free
    if free < need:
        raise LunarvizError(f"cannot write {str(path)!r}: {free:,} bytes free in {str(folder)!r}, about {need:,} "
                            f"needed")


def numbered_paths(out, n: int) -> list[Path]:
    """``out`` itself for one frame, else ``OUT_000.ext``, ``OUT_001.ext``, … for ``n`` frames."""
    out = Path(out)
    return [out] if n == 1 else [out.with_name(f"{out.stem}_{k:03d}{out.suffix}") for k in range(n)]


class StagedFiles:
    """Several outputs written all or nothing (numbered frames and their GIF)::

        with StagedFiles() as files:
            for k, frame in enumerate(frames):
                write_png(files.stage(f"f_{k:03d}.png"), frame)   # any writer, to a staged path

    Each target is first written to a private temporary beside it; when the block ends without
    error every one is checked (non-empty), flushed to disk and moved into place; on any error
    (the interrupt included) none is, and the temporaries are removed."""

    def __init__(self):
        self._staged: list[tuple[str, Path]] = []

    def stage(self, target) -> Path:
        p = check_output_path(target, (Path(target).suffix.lower(),))
        tmp = _temp_beside(p)
        self._staged.append((tmp, p))
        return Path(tmp)

    def __enter__(self) -> "StagedFiles":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc_type is None:
                for tmp, p in self._staged:
                    _seal(tmp, p)
                for tmp, p in self._staged:
                    os.replace(tmp, p)
        except OSError as e:
            raise LunarvizError(f"cannot write {str(p)!r}: {e.strerror or e}") from None
        finally:
            for tmp, _ in self._staged:
                _remove(tmp)
            self._staged = []


def save_figure(fig, path, dpi: int = 120) -> None:
    """A matplotlib figure to ``path`` through :func:`write_bytes_atomic` (format by suffix):
    never half-written, never through a symlink at ``path``."""
    buf = io.BytesIO()
    fig.savefig(buf, format=Path(path).suffix.lstrip(".").lower() or "png", dpi=dpi)
    write_bytes_atomic(path, buf.getvalue())


def rows_csv(payload: dict) -> str:
    """``payload``'s rows as CSV text (every field any row has; empty where a row has none)."""
    rows = [json_safe(r) for r in payload.get("rows", [])]
    fields: list[str] = []
    for r in rows:
        fields += [k for k in r if k not in fields]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in fields})
    return buf.getvalue()


def write_results(path, payload: dict) -> None:
    """Write ``payload`` (with a ``rows`` list) as JSON, or its rows as CSV, atomically."""
    p = Path(path)
    if p.suffix.lower() == ".json":
        data = json.dumps(json_safe(payload), indent=2, allow_nan=False).encode()
    else:
        data = rows_csv(payload).encode()
    write_bytes_atomic(p, data)
