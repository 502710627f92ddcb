from os import PathLike
from typing import Any, Optional, Sequence, Union

_Path = Union[str, PathLike[str]]

def robustness(out_dir: str = ..., *, client: Any = ..., parts: Optional[int] = ...,
               plant: Union[None, _Path, dict[str, Any]] = ..., model: Optional[_Path] = ...,
               only_axes: Sequence[str] = ..., seed: int = ..., pairs: bool = ..., score_from: str = ...,
               duration_scale: float = ..., fit_method: str = ..., figures: bool = ..., threads: int = ...,
               verbose: bool = ..., **gains: Any) -> dict[str, Any]: ...

def calibrate(out_dir: str = ..., *, client: Any = ..., ki_grid: Sequence[float] = ..., axes: Sequence[str] = ...,
              passes: int = ..., threads: int = ..., verbose: bool = ...) -> dict[str, Any]: ...
