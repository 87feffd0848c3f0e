"""The trained network, run with onnxruntime on the CPU or a CUDA GPU (no PyTorch needed).

The ONNX file takes ``features`` (batch, 6, size, size) float32 and returns, per cell:
``objectness`` (batch, 1, size, size, sigmoid applied), ``offset`` (batch, 2, size, size:
predicted object centre minus cell centre, x and y in metres), ``class_prob`` (batch, 3,
size, size: softmax over car, pedestrian, cyclist), ``height`` (batch, 1, size, size:
the object's top, z in metres) and, in models trained since 2026-11-29, ``heading``
(batch, 2, size, size: cos and sin of twice the object's yaw, Apollo's ``heading_pt``;
a model without it gets its boxes' headings from their outlines alone). The grid it was
trained on is stored in the file's metadata (``grid``, JSON), so a model and its feature
grid cannot be mixed up.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.systems.perception.cnnseg.features import CHANNELS, GridSpec

__all__ = ["CLASSES", "DEFAULT_MODEL", "DEVICES", "OUTPUTS", "NetworkOutput", "OnnxNetwork"]

CLASSES = ("car", "pedestrian", "cyclist")
DEFAULT_MODEL = Path(__file__).resolve().parent / "cnnseg.onnx"
OUTPUTS = ("objectness", "offset", "class_prob", "height", "heading")  # the last optional
_REQUIRED = OUTPUTS[:4]
DEVICES = ("cpu", "cuda", "auto")


@dataclass(frozen=True)
class NetworkOutput:
    """The network's maps for one frame (see the module docstring for each)."""

    objectness: NDArray[np.float32]  # (size, size)
    offset: NDArray[np.float32]  # (2, size, size)
    class_prob: NDArray[np.float32]  # (3, size, size)
    height: NDArray[np.float32]  # (size, size)
    heading: NDArray[np.float32] | None = None  # (2, size, size), None: not predicted


class OnnxNetwork:
    """An exported CNN segmentation network.

    Parameters
    ----------
    path : str or PathLike, optional
        The ONNX file; the model shipped with the package by default.
    threads : int or None
        onnxruntime's intra-op threads; None lets onnxruntime choose (every core). Use 1
        when several processes share the machine (pytest-xdist, Dask workers).
    device : {"cpu", "cuda", "auto"}
        Where the network runs. ``"cuda"`` needs onnxruntime's CUDA provider
        (``pip install onnxruntime-gpu``) and a GPU, and fails clearly without them;
        ``"auto"`` takes the GPU when onnxruntime offers one, else the CPU. On a GPU the
        maps differ from the CPU's by float rounding (the learned tolerance profile
        absorbs it); runs on one device are deterministic.

    Notes
    -----
    The session is created on first use and not pickled, so a detector holding one can
    travel to Dask workers and process pools.
    """

    def __init__(
        self,
        path: str | os.PathLike[str] | None = None,
        *,
        threads: int | None = 1,
        device: str = "auto",
    ):
        self.path = Path(DEFAULT_MODEL if path is None else path)
        if not self.path.is_file():
            what = "is not a regular file" if self.path.exists() else "does not exist"
            raise InvalidArgument(f"model file {str(self.path)!r} {what}")
        if threads is not None and (
            isinstance(threads, bool) or not isinstance(threads, int) or threads < 1
        ):
            raise InvalidArgument(f"threads={threads!r} must be an int >= 1 or None")
        if device not in DEVICES:
            raise InvalidArgument(f"device={device!r} must be one of {DEVICES}")
        self.threads = threads
        self.device = device
        self._session: Any = None
        self._grid: GridSpec | None = None
        self._outputs: tuple[str, ...] | None = None

    def __repr__(self) -> str:
        return f"OnnxNetwork({str(self.path)!r}, threads={self.threads}, device={self.device!r})"

    def __getstate__(self) -> dict[str, Any]:
        # The shipped model travels as "the shipped model": a worker finds its own copy
        # wherever the package is installed there.
        shipped = self.path == DEFAULT_MODEL
        return {
            "path": None if shipped else self.path,
            "threads": self.threads,
            "device": self.device,
        }

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.path = DEFAULT_MODEL if state["path"] is None else state["path"]
        self.threads = state["threads"]
        self.device = state.get("device", "cpu")
        self._session = None
        self._grid = None
        self._outputs = None

    @property
    def session(self) -> Any:
        """The onnxruntime ``InferenceSession`` (created on first use)."""
        if self._session is None:
            self._session = _open(self.path, self.threads, self.device)
        return self._session

    @property
    def on_gpu(self) -> bool:
        """Whether the session runs on onnxruntime's CUDA provider."""
        return "CUDAExecutionProvider" in self.session.get_providers()

    @property
    def grid(self) -> GridSpec:
        """The feature grid the model was trained on (from the file's metadata)."""
        if self._grid is None:
            meta = self.session.get_modelmeta().custom_metadata_map
            grid = _grid_from_metadata(meta, str(self.path))
            _check_input_shape(self.session, grid, str(self.path))
            self._grid = grid
        return self._grid

    def metadata(self) -> dict[str, str]:
        """Everything the training script stored in the file (grid, seed, data, quality)."""
        return dict(self.session.get_modelmeta().custom_metadata_map)

    def predict(self, features: NDArray[np.float32]) -> list[NetworkOutput]:
        """Run the network on a batch.

        Parameters
        ----------
        features : (batch, 6, size, size) float32

        Returns
        -------
        list of NetworkOutput, one per frame of the batch
        """
        grid = self.grid
        expected = (len(CHANNELS), grid.size, grid.size)
        if features.ndim != 4 or features.shape[1:] != expected:
            raise InvalidArgument(
                f"features must have shape (batch, {', '.join(map(str, expected))}), "
                f"got {features.shape}"
            )
        names = self.outputs
        values = self.session.run(
            list(names), {"features": np.ascontiguousarray(features, dtype=np.float32)}
        )
        objectness, offset, class_prob, height = values[:4]
        heading = values[4] if len(names) > 4 else None
        return [
            NetworkOutput(
                objectness[i, 0],
                offset[i],
                class_prob[i],
                height[i, 0],
                None if heading is None else heading[i],
            )
            for i in range(len(features))
        ]

    @property
    def outputs(self) -> tuple[str, ...]:
        """The maps this model gives (:data:`OUTPUTS`, ``heading`` only where trained)."""
        if self._outputs is None:
            have = {item.name for item in self.session.get_outputs()}
            missing = [name for name in _REQUIRED if name not in have]
            if missing:
                raise InvalidArgument(
                    f"model file {str(self.path)!r} has no output(s) {missing} (it has "
                    f"{sorted(have)}); a CNN segmentation model gives {list(_REQUIRED)}"
                )
            self._outputs = tuple(name for name in OUTPUTS if name in have)
        return self._outputs


_MAX_GRID_METADATA = 4096  # characters of the "grid" entry: a few numbers need ~100


def _grid_from_metadata(meta: Any, path: str) -> GridSpec:
    """The ``grid`` metadata entry as a GridSpec, every failure naming the file and field."""
    where = f"model file {path!r}: metadata 'grid'"
    if "grid" not in meta:
        raise InvalidArgument(f"model file {path!r} has no 'grid' metadata")
    text = meta["grid"]
    if not isinstance(text, str) or len(text) > _MAX_GRID_METADATA:
        size = len(text) if isinstance(text, str) else type(text).__name__
        raise InvalidArgument(f"{where} is {size} characters; at most {_MAX_GRID_METADATA}")
    try:
        data = json.loads(text)
    except RecursionError:
        raise InvalidArgument(f"{where} is nested too deeply to parse") from None
    except ValueError as error:
        raise InvalidArgument(f"{where} is not JSON ({error})") from None
    if not isinstance(data, dict):
        raise InvalidArgument(f"{where} must be a JSON object, got {type(data).__name__}")
    unknown = sorted(set(data) - {"size", "range", "min_height", "max_height"})
    if unknown:
        raise InvalidArgument(f"{where} has unknown field(s) {unknown}")
    try:
        return GridSpec(**data)
    except InvalidArgument as error:
        raise InvalidArgument(f"{where}: {error}") from None


def _check_input_shape(session: Any, grid: GridSpec, path: str) -> None:
    """The network's declared input must be the grid's: a model and a grid that do not
    belong together are refused before any frame runs (not by onnxruntime mid-run)."""
    inputs = {item.name: item.shape for item in session.get_inputs()}
    if "features" not in inputs:
        raise InvalidArgument(
            f"model file {path!r} has no input named 'features' (it has {sorted(inputs)})"
        )
    shape = list(inputs["features"])
    expected = [len(CHANNELS), grid.size, grid.size]
    declared = shape[1:]
    if len(shape) != 4 or any(
        isinstance(d, int) and d != e for d, e in zip(declared, expected, strict=True)
    ):
        raise InvalidArgument(
            f"model file {path!r}: its network takes features of shape {shape}, but its "
            f"'grid' metadata says {grid.size} x {grid.size} cells of {len(CHANNELS)} "
            "channels; the model and its grid do not belong together"
        )


def _providers(onnxruntime: Any, device: str) -> list[Any]:
    """onnxruntime's execution providers for ``device``, the CPU always last."""
    available = onnxruntime.get_available_providers()
    has_cuda = "CUDAExecutionProvider" in available
    if device == "cuda" and not has_cuda:
        raise InvalidArgument(
            "device='cuda' needs onnxruntime's CUDA provider, which this onnxruntime "
            f"does not have (it offers {available}): pip install onnxruntime-gpu, on a "
            "machine with an NVIDIA GPU"
        )
    if device == "cpu" or not has_cuda:
        return ["CPUExecutionProvider"]
    # Heuristic convolution search: the same algorithms every session, so repeated
    # runs of one input agree (an exhaustive search may pick others per session).
    cuda = ("CUDAExecutionProvider", {"cudnn_conv_algo_search": "HEURISTIC"})
    return [cuda, "CPUExecutionProvider"]


def _open(path: Path, threads: int | None, device: str = "cpu") -> Any:
    try:
        import onnxruntime
    except ImportError:
        raise InvalidArgument(
            "the CNN segmentation model needs onnxruntime: pip install "
            "'pytest-metamorphic[learned]'"
        ) from None
    options = onnxruntime.SessionOptions()
    options.use_deterministic_compute = True
    providers = _providers(onnxruntime, device)
    if threads is not None:
        options.intra_op_num_threads = threads
        options.inter_op_num_threads = 1
    try:
        return onnxruntime.InferenceSession(str(path), sess_options=options, providers=providers)
    except Exception as error:  # onnxruntime raises its own types for bad files
        raise InvalidArgument(
            f"model file {str(path)!r} is not a usable ONNX model: {error}"
        ) from None
