"""Byte-reproducible ``.npz`` and ``.mat`` files.

NumPy's ``savez`` stamps every member of the zip archive with the current local time, and SciPy's
``savemat`` writes ``Created on: <now>`` into the 116-byte text header of a MATLAB 5 file. The
same job run twice would therefore give different bytes. The writers here store a fixed time
instead:

* ``SOURCE_DATE_EPOCH`` (seconds since 1970, UTC; the convention of reproducible builds) when
  that environment variable is set,
* else 1980-01-01 00:00:00, the earliest time a zip archive can hold.

Everything else is unchanged: the archives are read by ``numpy.load`` (no pickles) and the
``.mat`` files by ``scipy.io.loadmat`` and MATLAB. Both writers go through
:func:`pymorembs.io.atomic.atomic_path`.
"""

from __future__ import annotations

import calendar
import os
import time
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import scipy.io

from pymorembs.io.atomic import atomic_path

#: The time stored when ``SOURCE_DATE_EPOCH`` is not set (the zip format's earliest).
DEFAULT_TIME = (1980, 1, 1, 0, 0, 0)
#: Length of the descriptive text at the start of a MATLAB 5 file.
MAT_HEADER_TEXT = 116


def fixed_time() -> tuple[int, int, int, int, int, int]:
    """(year, month, day, hour, minute, second) to store as creation time, UTC.

    ``SOURCE_DATE_EPOCH`` if set to a whole number (clamped to 1980-2107, the zip range), else
    :data:`DEFAULT_TIME`.
    """
    value = os.environ.get("SOURCE_DATE_EPOCH", "").strip()
    if not value.isdigit():
        return DEFAULT_TIME
    stamp = time.gmtime(int(value))[:6]
    return max(DEFAULT_TIME, min(stamp, (2107, 12, 31, 23, 59, 58)))  # type: ignore[return-value]


def write_npz(
    target: str | os.PathLike[str], arrays: Mapping[str, Any], compress: bool = False
) -> Path:
    """Write ``arrays`` as a ``.npz`` archive with fixed member times, atomically.

    Parameters
    ----------
    target : path-like
        The file (no extension is appended).
    arrays : mapping of str to array-like
        Member names (``.npy`` is appended) and arrays; object arrays are refused (no pickles).
    compress : bool
        Deflate the members (as ``numpy.savez_compressed``).

    Returns
    -------
    Path
    """
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    stamp = fixed_time()
    with (
        atomic_path(target) as tmp,
        zipfile.ZipFile(tmp, "w", compression=method, allowZip64=True) as archive,
    ):
        for key, value in arrays.items():
            info = zipfile.ZipInfo(f"{key}.npy", date_time=stamp)
            info.compress_type = method
            info.external_attr = 0o644 << 16
            with archive.open(info, "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)
    return Path(target)


def write_mat(target: str | os.PathLike[str], data: Mapping[str, Any], **options: Any) -> Path:
    """``scipy.io.savemat(data, **options)`` with a fixed header text, atomically.

    The 116-byte header becomes ``MATLAB 5.0 MAT-file, Platform: pymorembs, Created on: <fixed
    time>``; MATLAB and SciPy read the version and byte-order fields after it, not the text.
    """
    stamp = time.asctime(time.gmtime(calendar.timegm((*fixed_time(), 0, 0, 0))))
    header = f"MATLAB 5.0 MAT-file, Platform: pymorembs, Created on: {stamp}".encode("ascii")
    header = header.ljust(MAT_HEADER_TEXT, b" ")
    with atomic_path(target) as tmp:
        with open(tmp, "wb") as fh:  # a file object: savemat appends no ".mat"
            scipy.io.savemat(fh, dict(data), **options)
        with open(tmp, "r+b") as fh:
            if fh.read(len(b"MATLAB 5.0")) == b"MATLAB 5.0":  # only version 5 has the text
                fh.seek(0)
                fh.write(header)
    return Path(target)


__all__ = ["fixed_time", "write_mat", "write_npz"]
