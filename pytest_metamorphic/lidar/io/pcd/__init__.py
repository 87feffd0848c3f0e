"""PCD files (Point Cloud Library format v0.7): ``ascii``, ``binary``, ``binary_compressed``.

Reading maps the fields ``x``, ``y``, ``z`` and ``intensity`` onto the cloud's float32
columns and keeps every other field with its own dtype (``COUNT`` > 1 gives an ``(n, k)``
field); ``_`` padding fields are skipped. Writing produces files PCL, CloudCompare and
Open3D open. The header is checked against the file size before anything is allocated,
so a header that lies about its size gets a :class:`DataError`, not a memory blow-up.

The cloud's ``frame_id`` and ``timestamp`` have no PCD field; the writer keeps them in
two comment lines (``# frame_id ...``, ``# timestamp ...``) that this reader restores and
other tools ignore.

Modules: :mod:`.header` (parsing and checking headers, the canonical fast path),
:mod:`.payload` (ascii, binary and LZF-compressed bodies) and :mod:`.files`
(:func:`read_pcd`, :func:`write_pcd`, :func:`read_pcd_header`).
"""

from pytest_metamorphic.lidar.io.pcd.files import read_pcd, read_pcd_header, write_pcd
from pytest_metamorphic.lidar.io.pcd.header import PcdHeader

__all__ = ["PcdHeader", "read_pcd", "read_pcd_header", "write_pcd"]
