"""Type stubs of the native module (crates/jointfit-py/src). SI units: m, rad, s, Hz."""

import os
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, "os.PathLike[str]"]

__version__: str
BUILTIN_MODELS: List[str]
MARKER_SET_PRESETS: List[str]

class JointfitError(Exception):
    """An error of jointfit; the message is the command line's for the same failure."""

class JointfitWarning(UserWarning):
    """The warnings of one call, summarized in one warning; `details` lists each of them."""

    details: List[str]

_Progress = Union[None, bool, Callable[[str, int, float], Any]]

class Trial:
    """Marker trajectories of one trial, in the model's Y-up frame."""

    @staticmethod
    def read(
        path: _Path,
        up: Optional[str] = None,
        filter: Optional[float] = None,
        model: Optional[Union[Model, _Path]] = None,
    ) -> Trial: ...
    def repair(
        self,
        exclude: Optional[Sequence[str]] = None,
        swap: Optional[Sequence[str]] = None,
        fill_gaps: Optional[int] = None,
        model: Optional[Union[Model, _Path]] = None,
    ) -> Tuple[Trial, List[str]]: ...
    @staticmethod
    def from_arrays(
        labels: Sequence[str],
        markers: npt.ArrayLike,
        rate: float,
        first_frame: Optional[int] = None,
        name: Optional[str] = None,
        times: Optional[npt.ArrayLike] = None,
    ) -> Trial:
        """(frames, markers, 3) metres, any real dtype or nested lists; NaN for gaps."""
    @property
    def labels(self) -> List[str]: ...
    @property
    def rate(self) -> float: ...
    @property
    def first_frame(self) -> int: ...
    @property
    def name(self) -> str: ...
    @property
    def markers(self) -> npt.NDArray[np.float64]:
        """(frames, markers, 3), metres, NaN for gaps."""
    @property
    def times(self) -> List[float]: ...
    @property
    def duration(self) -> float: ...
    def filtered(self, cutoff: float) -> Trial: ...
    def select(self, labels: Sequence[str]) -> Trial: ...
    def between(self, t0: float, t1: float) -> Trial:
        """Frames with t0 <= time <= t1 (s), keeping their times and frame numbers."""
    def write_trc(
        self, path: _Path, units: Optional[str] = None, decimals: Optional[int] = None
    ) -> None: ...
    def __len__(self) -> int: ...
    def __eq__(self, other: object) -> bool: ...

class Model:
    """A kinematic leg model with its joint parameters."""

    @staticmethod
    def load(path_or_builtin: _Path) -> Model: ...
    @staticmethod
    def from_toml(text: str) -> Model: ...
    def to_toml(self) -> str: ...
    def save(self, path: _Path) -> None: ...
    @property
    def name(self) -> str: ...
    @property
    def parameters(self) -> Dict[str, float]: ...
    @property
    def bounds(self) -> Dict[str, Tuple[float, float]]: ...
    @property
    def groups(self) -> Dict[str, List[str]]: ...
    @property
    def units(self) -> Dict[str, str]: ...
    @property
    def coordinate_names(self) -> List[str]: ...
    @property
    def marker_names(self) -> List[str]: ...
    def with_parameters(self, values: Dict[str, float]) -> Model: ...

class IkResult:
    @property
    def coordinates(self) -> npt.NDArray[np.float64]:
        """(frames, n_coordinates), rad / m; NaN rows where not solved."""
    @property
    def coordinate_names(self) -> List[str]: ...
    @property
    def marker_names(self) -> List[str]: ...
    @property
    def errors(self) -> npt.NDArray[np.float64]:
        """(frames, markers) marker distances, m, NaN where missing."""
    @property
    def rms(self) -> npt.NDArray[np.float64]:
        """Per-frame RMS marker distance, m."""
    @property
    def solved(self) -> npt.NDArray[np.bool_]: ...
    @property
    def times(self) -> npt.NDArray[np.float64]: ...
    @property
    def units(self) -> Dict[str, str]:
        """Coordinate name -> "rad" or "m"."""
    def to_dataframe(self, degrees: Optional[bool] = None) -> Any:
        """pandas.DataFrame: index time (s), one column per coordinate."""
    def to_xarray(self) -> Any:
        """xarray.DataArray (time, coordinate)."""
    def write_mot(self, path: _Path) -> None:
        """OpenSim .mot: rotations in degrees, the trial's own time."""
    def __len__(self) -> int: ...

class StreamingIK:
    """Inverse kinematics of a live marker feed, one frame per `update` (GIL released)."""

    def __init__(
        self,
        model: _ModelArg,
        labels: Sequence[str],
        up: Optional[str] = None,
        hold_undetermined: bool = False,
        keep_outliers: bool = False,
    ) -> None: ...
    def update(
        self, markers: npt.NDArray[np.float64], time: Optional[float] = None
    ) -> npt.NDArray[np.float64]:
        """markers (len(labels), 3) in m, lab frame, NaN if missing -> coordinates (rad, m),
        NaN when the frame cannot be solved."""
    def reset(self) -> None: ...
    @property
    def coordinate_names(self) -> List[str]: ...
    @property
    def marker_names(self) -> List[str]: ...
    @property
    def absent(self) -> List[str]: ...
    @property
    def held(self) -> List[str]: ...
    @property
    def solved(self) -> bool: ...
    @property
    def status(self) -> Optional[str]: ...
    @property
    def errors(self) -> npt.NDArray[np.float64]:
        """(markers,), m, the last frame's marker distances."""
    @property
    def rejected(self) -> List[str]: ...

class Calibration:
    @property
    def model(self) -> Model: ...
    @property
    def parameters(self) -> Dict[str, float]: ...
    @property
    def start(self) -> Dict[str, float]: ...
    @property
    def intervals(self) -> Dict[str, Optional[Tuple[float, float]]]: ...
    @property
    def standard_errors(self) -> Dict[str, Optional[float]]: ...
    @property
    def rms_before(self) -> float: ...
    @property
    def rms_after(self) -> float: ...
    @property
    def frames(self) -> Tuple[int, int]: ...
    @property
    def converged(self) -> bool: ...
    @property
    def iterations(self) -> int: ...
    @property
    def warnings(self) -> List[str]: ...
    @property
    def verdict(self) -> Verdict: ...
    def to_dict(self) -> dict: ...
    def to_json(self) -> str: ...
    def to_dataframe(self) -> Any:
        """pandas.DataFrame: one row per free parameter (SI units)."""
    def _repr_html_(self) -> str: ...

class Verdict:
    """How far to trust a fit: level "ok", "caution" or "reject", and the reasons."""
    @property
    def level(self) -> str: ...
    @property
    def reasons(self) -> List[str]: ...

_TrialArg = Union[Trial, _Path]
_ModelArg = Union[Model, _Path]

def personalize(
    static: _TrialArg,
    markers: str,
    side: Optional[str] = None,
    up: Optional[str] = None,
    hip: Optional[str] = None,
    window: Optional[float] = None,
    name: Optional[str] = None,
) -> Model: ...
def scale(
    model: Union[str, os.PathLike],
    static: Union[str, os.PathLike],
    trials: Sequence[Union[str, os.PathLike]] = (),
    markerset: Optional[Union[str, os.PathLike]] = None,
    mass: Optional[float] = None,
    height: Optional[float] = None,
    output: Optional[Union[str, os.PathLike]] = None,
    prior: str = "anthropometric",
    per_axis: bool = False,
    symmetric: bool = False,
    time_range: Optional[Tuple[float, float]] = None,
) -> Dict[str, Any]: ...
def ik(
    model: _ModelArg, trial: _TrialArg, up: Optional[str] = None, filter: Optional[float] = None
) -> IkResult: ...
def calibrate(
    model: _ModelArg,
    trials: Union[_TrialArg, Sequence[_TrialArg]],
    joints: Optional[Union[str, Sequence[str]]] = None,
    method: str = "joint",
    up: Optional[str] = None,
    filter: Optional[float] = None,
    seed: int = 1,
    bootstrap: int = 0,
    threshold_mm: float = 5.0,
    threshold_deg: float = 5.0,
    starts: int = 1,
    fix_unidentifiable: bool = False,
    prior: str = "model",
    marker_noise_mm: Optional[float] = None,
    max_iter: Optional[int] = None,
    params: Optional[Sequence[str]] = None,
    progress: _Progress = None,
    accept_rejected: bool = False,
) -> Calibration: ...
def _check_calibrate(model: Any, trials: Any, **options: Any) -> None: ...
def synthesize(
    model: Optional[_ModelArg] = None,
    motion: Optional[str] = None,
    frames: Optional[int] = None,
    rate: Optional[float] = None,
    noise_mm: Optional[float] = None,
    perturb: Optional[float] = None,
    seed: Optional[int] = None,
) -> Tuple[Trial, Model]: ...
def _calibration_from_json(text: str) -> Calibration: ...
