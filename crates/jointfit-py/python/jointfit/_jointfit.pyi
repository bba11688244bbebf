"""Type stubs of the native module (crates/jointfit-py/src). SI units: m, rad, s, Hz."""

import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, "os.PathLike[str]"]

__version__: str
BUILTIN_MODELS: List[str]
MARKER_SET_PRESETS: List[str]

class JointfitError(Exception):
    """An error of jointfit; the message is the command line's for the same failure."""

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
        exclude: Sequence[str] = ...,
        swap: Sequence[str] = ...,
        fill_gaps: int = 0,
        model: Optional[Union[Model, _Path]] = None,
    ) -> Tuple[Trial, List[str]]: ...
    @staticmethod
    def from_arrays(
        labels: Sequence[str],
        markers: npt.NDArray[np.float64],
        rate: float,
        first_frame: int = 0,
        name: Optional[str] = None,
    ) -> Trial: ...
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
    def filtered(self, cutoff: float) -> Trial: ...
    def select(self, labels: Sequence[str]) -> Trial: ...
    def __len__(self) -> int: ...

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
    def to_dict(self) -> dict: ...
    def to_json(self) -> str: ...

_TrialArg = Union[Trial, _Path]
_ModelArg = Union[Model, _Path]

def personalize(
    static: _TrialArg,
    markers: str,
    side: str = "both",
    up: Optional[str] = None,
    hip: str = "bell",
    window: float = 1.0,
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
) -> Calibration: ...
def synthesize(
    model: Optional[_ModelArg] = None,
    motion: str = "all",
    frames: int = 100,
    rate: float = 50.0,
    noise_mm: float = 10.0,
    perturb: float = 0.4,
    seed: int = 1,
) -> Tuple[Trial, Model]: ...
def _calibration_from_json(text: str) -> Calibration: ...
