"""Detectors in another process: frames out as files, predictions back as files.

Many perception stacks cannot be imported into the test process: a ROS 2 or C++ node, a
model in another virtual environment or on a GPU server. :class:`ProcessDetector` makes
such a stack a system under test, ``detector(frame) -> list[Box]``:

1. the frame's cloud is written to a file (KITTI ``.bin`` float32 x, y, z, intensity by
   default, or PCD);
2. the command runs on it and writes its predictions to a file;
3. the predictions are read back as boxes: JSON (see :func:`read_json_predictions`) or
   a KITTI label file (camera frame; converted with ``calibration``, by default the
   axis-swap :func:`~pytest_metamorphic.lidar.io.kitti.sensor_calibration`).

Two ways to run the command:

* **one process per frame** (default): ``command`` contains the placeholders
  ``{input}`` and ``{output}``, e.g. ``["python", "detect.py", "{input}", "{output}"]``;
  a non-zero exit status is an error naming the command, its status and its stderr.
* **one long-lived process** (``persistent=True``), so a model is loaded once: the
  command is started once; for each frame it is sent one line ``INPUT<TAB>OUTPUT`` on
  stdin, writes its predictions to OUTPUT, then prints one line on stdout that names the
  INPUT it answers (e.g. ``done<TAB>INPUT``, or the request line echoed; logs go to
  stderr). If it dies it is restarted for the next frame.
  With ``batch_size=k`` it may also be sent up to k frames in one line,
  ``INPUT1<TAB>OUTPUT1<TAB>INPUT2<TAB>OUTPUT2...``, and answers one line when every
  OUTPUT is written: campaigns and ``@metamorphic(batch=True)`` tests then hand it a
  source and its follow-ups together (:mod:`pytest_metamorphic.core.batching`), so a
  model can run them as one batch.

``timeout`` is the limit per frame in both modes; only the first request to a fresh
long-lived process also gets ``startup_timeout`` (loading a model). A program past its
limit is killed with its whole process group and the call raises
:class:`~pytest_metamorphic.core.errors.SystemTimeout`, which the engine and campaigns
report as a crash, never as a violation. A program that dies, writes a file that is not
predictions, or prints on stdout anything but its one answer line per request (a banner,
a second line) raises :class:`~pytest_metamorphic.core.errors.ExternalSystemError`
naming what it printed. Programs run in process groups of their own: helpers they fork
are killed with them, and cannot block a run by keeping its pipes open
(:mod:`pytest_metamorphic.core.processes`).

The contract, for a detector written in any language:

* **input**: ``.bin``, float32 little-endian x, y, z, intensity per point (KITTI), or a
  PCD file; metres in the LiDAR frame, x forward, y left, z up, origin at the sensor;
* **output, JSON**: ``{"boxes": [{"center": [x, y, z], "size": [length, width, height],
  "yaw": yaw, "label": "car", "score": 0.9}, ...]}`` with ``center`` the geometric centre
  of the box (not its bottom), ``length`` along the heading, ``yaw`` in radians
  counter-clockwise from +x about +z, all in the LiDAR frame. Labels are the project's
  (``car``, ``pedestrian``, ``cyclist``, ``unknown``) or the detector's own class names:
  KITTI's, nuScenes' and Waymo's are known
  (:data:`~pytest_metamorphic.lidar.systems.detectors.CLASS_LABELS`), others map through
  ``label_map=`` and otherwise become ``unknown``;
* **output, KITTI**: a label file (camera frame, bottom centre, h w l, ``rotation_y``,
  a score column), converted with ``calibration``;
* **stdout** (long-lived mode): exactly one line per request, written after the
  prediction files, naming every INPUT of the request; everything else (logs, banners)
  goes to stderr;
* **identity**: an answer that names a frame of an earlier request is an error (answers
  out of order), as is one naming only some of a batch's frames; an answer naming none
  (a plain ``done``) is accepted with a :class:`~pytest_metamorphic.core.errors.ProtocolWarning`,
  once per detector, since then a stale or reordered answer cannot be told. A JSON
  predictions file may also say which frame it is of, ``"input": "<INPUT path or its
  file name>"``; when it does, another frame's name is an error (a batch whose files were
  mixed up).
"""

from __future__ import annotations

import contextlib
import os
import shlex
import shutil
import tempfile
import threading
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

from pytest_metamorphic.core.errors import (
    DataError,
    ExternalSystemError,
    InvalidArgument,
    ProtocolWarning,
)
from pytest_metamorphic.core.files import read_json
from pytest_metamorphic.core.processes import LineChannel, run_command
from pytest_metamorphic.core.timeout import check_timeout
from pytest_metamorphic.lidar.io.kitti import (
    KittiCalibration,
    read_kitti_calibration,
    read_kitti_labels,
    sensor_calibration,
)
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.obstacles import LABELS, Box, Label
from pytest_metamorphic.lidar.systems.detectors import from_mmdet3d, from_openpcdet, label_mapping

__all__ = ["ProcessDetector", "boxes_to_json", "read_json_predictions"]


def boxes_to_json(boxes: Sequence[Box]) -> dict[str, Any]:
    """The JSON predictions format: ``{"boxes": [{"center", "size", "yaw", "label", "score"}]}``."""
    return {
        "boxes": [
            {
                "center": list(box.center),
                "size": list(box.size),
                "yaw": box.yaw,
                "label": box.label,
                "score": box.score,
            }
            for box in boxes
        ]
    }


def read_json_predictions(
    path: str | os.PathLike[str],
    *,
    class_names: Sequence[str] | None = None,
    label_map: Mapping[str, Label] | None = None,
    expect_input: str | os.PathLike[str] | None = None,
) -> list[Box]:
    """Boxes from a JSON predictions file.

    Accepted layouts: ``{"boxes": [...]}`` or a bare list of box objects (``center``: the
    geometric centre, ``size`` as length, width, height, ``yaw`` in radians about +z,
    ``label``, optional ``score``; see the module docstring and :func:`boxes_to_json`);
    OpenPCDet's ``{"pred_boxes", "pred_labels", "pred_scores"}`` or mmdetection3d's
    ``{"bboxes_3d", "labels_3d", "scores_3d"}``, which need ``class_names`` (see
    :mod:`pytest_metamorphic.lidar.systems.detectors`).

    Parameters
    ----------
    path : path-like
    class_names : sequence of str, optional
        For the array layouts: the detector's class names, by index.
    label_map : mapping, optional
        Class name -> label, on top of
        :data:`~pytest_metamorphic.lidar.systems.detectors.CLASS_LABELS` ("Car" is
        ``car``); a name neither knows becomes ``unknown``.
    expect_input : path-like, optional
        The frame these predictions must be of: a file whose ``"input"`` names another
        frame (a batch answered out of order, a stale file) is refused.
    """
    path = Path(path)
    mapping = label_mapping(label_map)
    data = read_json(path, what="JSON predictions file")
    if expect_input is not None and isinstance(data, Mapping) and "input" in data:
        _check_identity(data["input"], Path(expect_input), path)
    try:
        if isinstance(data, Mapping) and ("pred_boxes" in data or "bboxes_3d" in data):
            if class_names is None:
                raise DataError("OpenPCDet/mmdetection3d arrays need class_names=", path=path)
            convert = from_openpcdet if "pred_boxes" in data else from_mmdet3d
            return convert(dict(data), class_names=class_names, label_map=label_map)
        items = data.get("boxes") if isinstance(data, Mapping) else data
        if not isinstance(items, list):
            raise DataError('expected {"boxes": [...]} or a list of boxes', path=path)
        return [_box(item, index, mapping) for index, item in enumerate(items)]
    except InvalidArgument as error:
        raise DataError(str(error), path=path) from None


def _check_identity(named: Any, expected: Path, path: Path) -> None:
    """The predictions' ``"input"`` must name the frame they were asked for (its path, or
    its file name)."""
    if not isinstance(named, str) or named not in (str(expected), expected.name):
        raise DataError(
            f'predictions of "input": {str(named)[:200]!r}, but this file answers '
            f"{expected.name}: the detector mixed up its frames (a batch answered out of "
            "order, or a stale file)",
            path=path,
        )


def _box(item: Any, index: int, mapping: Mapping[str, Label]) -> Box:
    if not isinstance(item, Mapping):
        raise InvalidArgument(f"boxes[{index}] is {type(item).__name__}, not an object")
    missing = {"center", "size"} - set(item)
    if missing:
        raise InvalidArgument(f"boxes[{index}] has no {sorted(missing)}")
    name = item.get("label", "unknown")
    if not isinstance(name, str):
        raise InvalidArgument(f"boxes[{index}]: label must be a string")
    label: Label = name if name in LABELS else mapping.get(name, "unknown")
    try:
        return Box(
            tuple(item["center"]),
            tuple(item["size"]),
            float(item.get("yaw", 0.0)),
            label,
            None if item.get("score") is None else float(item["score"]),
        )
    except (TypeError, ValueError) as error:
        raise InvalidArgument(f"boxes[{index}]: {str(error)[:200]}") from None


class ProcessDetector:
    """A detector run as an external command (see the module docstring).

    Parameters
    ----------
    command : str or sequence of str
        The command line (a string is split like a shell would, without a shell).
    persistent : bool
        Start the command once and talk to it line by line (default: once per frame,
        with ``{input}`` and ``{output}`` in the command).
    input_format : {"bin", "pcd"}
        How frames are handed over.
    output_format : {"json", "kitti"}
        What the command writes.
    calibration : path or KittiCalibration, optional
        For ``output_format="kitti"``: how the labels' camera frame relates to the LiDAR
        (default :func:`~pytest_metamorphic.lidar.io.kitti.sensor_calibration`).
    class_names : sequence of str, optional
        For JSON predictions in OpenPCDet's or mmdetection3d's array layout.
    label_map : mapping, optional
        The detector's class names -> the project's labels, on top of the known names
        (``"Car"``, ``"Pedestrian"``, nuScenes', Waymo's); see :func:`read_json_predictions`.
    timeout : float or None
        Seconds per frame, in both modes (default 60); a program past it is killed.
    startup_timeout : float
        Extra seconds for the first request to a fresh long-lived process (loading a
        model); not used per frame.
    env, cwd
        The command's environment (added to this process's) and working directory.
    batch_size : int, optional
        For ``persistent=True``: the process understands requests of up to this many
        frames (see the module docstring), and :meth:`run_batch` sends them. None (the
        default): one frame per request.
    """

    def __init__(
        self,
        command: str | Sequence[str],
        *,
        persistent: bool = False,
        input_format: Literal["bin", "pcd"] = "bin",
        output_format: Literal["json", "kitti"] = "json",
        calibration: str | os.PathLike[str] | KittiCalibration | None = None,
        class_names: Sequence[str] | None = None,
        label_map: Mapping[str, Label] | None = None,
        timeout: float | None = 60.0,
        startup_timeout: float = 60.0,
        env: Mapping[str, str] | None = None,
        cwd: str | os.PathLike[str] | None = None,
        batch_size: int | None = None,
    ) -> None:
        self.command = _as_command(command)
        if not isinstance(persistent, bool):
            raise InvalidArgument(f"persistent={persistent!r} must be True or False")
        placeholders = any("{input}" in part or "{output}" in part for part in self.command)
        if not persistent and not (
            any("{input}" in part for part in self.command)
            and any("{output}" in part for part in self.command)
        ):
            raise InvalidArgument(
                f"command {self.command!r} needs the placeholders {{input}} and {{output}} "
                "(or persistent=True for a process that reads requests from stdin)"
            )
        if persistent and placeholders:
            raise InvalidArgument(
                "a persistent command gets its files on stdin; remove {input}/{output}"
            )
        if input_format not in ("bin", "pcd"):
            raise InvalidArgument(f"input_format={input_format!r} must be 'bin' or 'pcd'")
        if output_format not in ("json", "kitti"):
            raise InvalidArgument(f"output_format={output_format!r} must be 'json' or 'kitti'")
        if calibration is not None and output_format != "kitti":
            raise InvalidArgument("calibration= is only used with output_format='kitti'")
        if shutil.which(self.command[0]) is None and not Path(self.command[0]).is_file():
            raise InvalidArgument(f"command {self.command[0]!r} not found (PATH or a file)")
        if batch_size is not None:
            if isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1:
                raise InvalidArgument(f"batch_size={batch_size!r} must be an int >= 1 or None")
            if not persistent:
                raise InvalidArgument(
                    "batch_size= needs persistent=True (batches go to a long-lived process)"
                )
        self.batch_size = batch_size
        self.persistent = persistent
        self.input_format = input_format
        self.output_format = output_format
        self.calibration = calibration
        self.class_names = None if class_names is None else list(class_names)
        label_mapping(label_map)  # checked now, not on the first frame
        self.label_map = None if label_map is None else dict(label_map)
        self.timeout = check_timeout(timeout)
        self.startup_timeout = check_timeout(startup_timeout, "startup_timeout") or 0.0
        self.env = None if env is None else {**os.environ, **dict(env)}
        self.cwd = None if cwd is None else str(cwd)
        self.calls = 0
        self.starts = 0
        self._channel: LineChannel | None = None
        self._lock = threading.Lock()
        self._calib: KittiCalibration | None = None
        self._answered: list[str] = []  # the frames of the last request answered
        self._warned_anonymous = False

    def __repr__(self) -> str:
        mode = "persistent" if self.persistent else "per frame"
        return f"ProcessDetector({shlex.join(self.command)!r}, {mode})"

    def __getstate__(self) -> dict[str, Any]:
        # Sent to workers (xdist, Dask) without the running process; each starts its own.
        state = self.__dict__.copy()
        state.update(_channel=None, _lock=None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._lock = threading.Lock()

    def __enter__(self) -> ProcessDetector:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            self.close()

    @property
    def running(self) -> bool:
        """Whether a long-lived process is up (it is started on the next request if not)."""
        return self._channel is not None and self._channel.alive()

    def close(self) -> None:
        """Stop the long-lived process, if one is running (with its process group)."""
        channel, self._channel = self._channel, None
        if channel is not None:
            channel.close()

    def __call__(self, frame: Any, roi: Any = None) -> list[Box]:
        """Run the command on ``frame`` (a Frame, a PointCloud or an (n, 4) array)."""
        cloud = _as_cloud(frame)
        with self._lock, tempfile.TemporaryDirectory(prefix="mt-process-") as folder:
            ((source, target),) = self._files(Path(folder), 1)
            self._write(cloud, source)
            self.calls += 1
            if self.persistent:
                self._request([(source, target)])
            else:
                self._run_once(source, target)
            return self._read(target, source)

    def run_batch(self, frames: Sequence[Any]) -> list[list[Box]]:
        """Run the command on several frames in one request (needs ``batch_size``).

        Returns one list of boxes per frame, in order. The request may take ``timeout``
        seconds per frame.
        """
        if self.batch_size is None:
            raise InvalidArgument(
                f"{self!r} takes one frame per request; give batch_size= to send batches"
            )
        if len(frames) > self.batch_size:
            raise InvalidArgument(f"{len(frames)} frames exceed batch_size={self.batch_size}")
        clouds = [_as_cloud(frame) for frame in frames]
        if not clouds:
            return []
        with self._lock, tempfile.TemporaryDirectory(prefix="mt-process-") as folder:
            files = self._files(Path(folder), len(clouds))
            for cloud, (source, _) in zip(clouds, files, strict=True):
                self._write(cloud, source)
            self.calls += len(clouds)
            self._request(files)
            return [self._read(target, source) for source, target in files]

    def _files(self, folder: Path, count: int) -> list[tuple[Path, Path]]:
        suffix = "json" if self.output_format == "json" else "txt"
        tags = [""] if count == 1 else [str(i) for i in range(count)]
        return [
            (folder / f"frame{tag}.{self.input_format}", folder / f"predictions{tag}.{suffix}")
            for tag in tags
        ]

    # -- handing over ----------------------------------------------------------------------

    def _write(self, cloud: PointCloud, path: Path) -> None:
        from pytest_metamorphic.lidar.io import write_bin, write_pcd

        if self.input_format == "bin":
            write_bin(cloud, path)
        else:
            write_pcd(cloud, path)

    def _read(self, path: Path, source: Path | None = None) -> list[Box]:
        if not path.is_file():
            raise ExternalSystemError(
                f"{self._name()} wrote no predictions to {path.name} (expected a "
                f"{self.output_format} file there)"
            )
        try:
            if self.output_format == "json":
                return read_json_predictions(
                    path,
                    class_names=self.class_names,
                    label_map=self.label_map,
                    expect_input=source,
                )
            return read_kitti_labels(path, self._calibration())
        except DataError as error:
            self._stray_answer()
            raise ExternalSystemError(f"{self._name()} wrote garbage: {error}") from None

    def _stray_answer(self) -> None:
        """A long-lived program whose predictions are incomplete may have had a stray line
        (a banner) taken for its answer while it was still writing: if its real answer
        follows within a second, name the stray line instead of blaming the file."""
        channel = self._channel
        if not self.persistent or channel is None:
            return
        later = channel.output_within(1.0)
        if later:
            first = channel.last_answer or ""
            self.close()
            raise ExternalSystemError(
                f"{self._name()} printed {first[:200]!r} on stdout before its predictions "
                f"were written, then {later[:200]!r}: the first line was not its answer. "
                "stdout is reserved for one answer line per request, written after the "
                "files (a library banner or a print there breaks the protocol); log to stderr"
            )

    def _calibration(self) -> KittiCalibration:
        if self._calib is None:
            given = self.calibration
            if given is None:
                self._calib = sensor_calibration()
            elif isinstance(given, KittiCalibration):
                self._calib = given
            else:
                self._calib = read_kitti_calibration(given)
        return self._calib

    def _name(self) -> str:
        return f"command {shlex.join(self.command)!r}"

    # -- one process per frame -------------------------------------------------------------

    def _run_once(self, source: Path, target: Path) -> None:
        # Only the two placeholders are replaced: other braces in an argument (a Python
        # snippet's "{}", a JSON literal) are the user's text, not a format string.
        args = [
            part.replace("{input}", str(source)).replace("{output}", str(target))
            for part in self.command
        ]
        self.starts += 1
        run_command(args, name=self._name(), timeout=self.timeout, env=self.env, cwd=self.cwd)

    # -- one long-lived process ------------------------------------------------------------

    def _request(self, files: Sequence[tuple[Path, Path]]) -> None:
        limit = None if self.timeout is None else self.timeout * len(files)
        channel = self._channel
        if channel is None or not channel.alive():
            self.close()
            channel = self._channel = LineChannel(
                self.command, name=self._name(), env=self.env, cwd=self.cwd
            )
            self.starts += 1
            if limit is not None:
                limit += self.startup_timeout  # loading the model: the first request only
        line = "\t".join(f"{source}\t{target}" for source, target in files)
        try:
            answer = channel.request(line, timeout=limit)
            self._check_answer(answer, [source for source, _ in files])
            missing = [target.name for _, target in files if not target.exists()]
            if missing:
                raise ExternalSystemError(
                    f"{self._name()} answered {answer[:200]!r} before writing {missing[0]}: "
                    "if that line is a banner or a log line, print it to stderr (stdout is "
                    "reserved for one answer line per request, written after the files)"
                )
        except BaseException:
            # Timed out, died or broke the protocol: killed; started afresh next time.
            self.close()
            raise

    def _check_answer(self, answer: str, inputs: Sequence[Path]) -> None:
        """An answer line names the frames it answers (the contract); one that names
        another request's frame is out of order, one that names none cannot be checked
        (warned once)."""
        named = [str(source) for source in inputs if str(source) in answer]
        earlier = [path for path in self._answered if path in answer]
        self._answered = [str(source) for source in inputs]
        if earlier and not named:
            raise ExternalSystemError(
                f"{self._name()} answered {answer[:200]!r} to a request for "
                f"{inputs[0].name}: that names a frame of an earlier request (answers out of "
                "order)"
            )
        if named and len(named) != len(inputs):
            missing = [source.name for source in inputs if str(source) not in named]
            raise ExternalSystemError(
                f"{self._name()} answered {answer[:200]!r}, which names {len(named)} of the "
                f"request's {len(inputs)} frames (not {', '.join(missing[:3])})"
            )
        if not named and not self._warned_anonymous:
            self._warned_anonymous = True
            warnings.warn(
                f"{self._name()} answered {answer[:80]!r}, which names no frame of the "
                "request: answers out of order or stale cannot be detected. Answer with the "
                "request's INPUT path(s), e.g. echo the request line (see "
                "pytest_metamorphic.lidar.systems.process)",
                ProtocolWarning,
                stacklevel=4,
            )


def _as_command(command: Any) -> list[str]:
    if isinstance(command, str):
        parts = shlex.split(command)
    elif isinstance(command, Sequence) and all(
        isinstance(part, (str, os.PathLike)) for part in command
    ):
        parts = [os.fspath(part) for part in command]
    else:
        raise InvalidArgument(f"command={command!r} must be a string or a list of strings")
    if not parts:
        raise InvalidArgument("command is empty")
    return parts


def _as_cloud(frame: Any) -> PointCloud:
    cloud = getattr(frame, "cloud", frame)
    if isinstance(cloud, PointCloud):
        return cloud
    return PointCloud(cloud, name="frame")
