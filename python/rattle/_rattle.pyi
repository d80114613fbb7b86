"""Type stubs of the extension module (the package's `__init__.py` wraps it)."""

from os import PathLike
import numpy
from typing import Any, Callable, Dict, List, Optional, Tuple

_Progress = Optional[Callable[[int, int], Any]]

__version__: str

def point(
    path: Optional[str], text: Optional[str], sets: List[str], progress: _Progress = None
) -> Tuple[str, List[str]]: ...

class MapData:
    warnings: List[str]
    def layers(self) -> Dict[str, bytes]: ...
    def report(self) -> str: ...
    def save(self, prefix: "str | PathLike[str]") -> List[str]: ...

def map(
    path: Optional[str], text: Optional[str], sets: List[str], progress: _Progress = None
) -> MapData: ...

class BifurcationData:
    warnings: List[str]
    def samples(self) -> Tuple[List[str], "numpy.ndarray", "numpy.ndarray", "numpy.ndarray"]: ...
    def report(self) -> str: ...
    def save(self, prefix: "str | PathLike[str]") -> List[str]: ...

def bifurcation(
    path: Optional[str], text: Optional[str], sets: List[str], progress: _Progress = None
) -> BifurcationData: ...

class SensitivityData:
    warnings: List[str]
    def report(self) -> str: ...
    def draws(self) -> Tuple[List[str], List[int], List[List[float]], List[str], List[float]]: ...
    def save(self, prefix: "str | PathLike[str]") -> List[str]: ...

def sensitivity(
    path: Optional[str],
    text: Optional[str],
    sets: List[str],
    uncertain: Optional[List[str]] = None,
    samples: Optional[int] = None,
    seed: Optional[int] = None,
    progress: _Progress = None,
) -> SensitivityData: ...

class BasinData:
    warnings: List[str]
    def ids(self) -> bytes: ...
    def report(self) -> str: ...
    def save(self, prefix: "str | PathLike[str]") -> List[str]: ...

def basin(
    path: Optional[str], text: Optional[str], sets: List[str], progress: _Progress = None
) -> BasinData: ...

def bench(
    path: Optional[str],
    text: Optional[str],
    sets: List[str],
    points: Optional[int] = None,
    periods: Optional[int] = None,
    backends: Optional[List[str]] = None,
) -> Tuple[str, List[str]]: ...
def validate(
    path: Optional[str], text: Optional[str], sets: List[str], state_points: Optional[int] = None
) -> Tuple[str, List[str]]: ...
