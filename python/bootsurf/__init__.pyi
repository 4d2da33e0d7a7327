# Type stubs of the bootsurf package (python/bootsurf/__init__.py).
import os
from typing import Any, Callable, Dict, List, Literal, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

ArrayLike = npt.ArrayLike
PathLike = Union[str, os.PathLike]
Progress = Optional[Callable[[int, int], Any]]
Points = Union[ArrayLike, Mapping[str, Any], PathLike]

class Cloud(Dict[str, np.ndarray]):
    shape_name: str
    def __init__(self, *args: Any, shape_name: str = ..., **kwargs: Any) -> None: ...

def read(path: PathLike) -> Cloud: ...
def write(
    path: PathLike,
    cloud: Union[Mapping[str, ArrayLike], ArrayLike],
    *,
    ascii: bool = ...,
    format: Optional[Literal["ply", "pcd", "las", "csv", "asc", "xyz", "txt", "pts", "off", "obj"]] = ...,
    float32: bool = ...,
    ply_names: Literal["plain", "cloudcompare", "meshlab"] = ...,
    las_version: Literal["1.2", "1.4"] = ...,
) -> None: ...
def knn(
    points: ArrayLike, k: int, *, threads: int = ..., progress: Progress = ...
) -> Tuple[npt.NDArray[np.uint32], npt.NDArray[np.float64]]: ...
def spacing(points: Points, *, threads: int = ..., progress: Progress = ...) -> float: ...
def error(
    points: Points,
    *,
    neighbors: int = ...,
    degree: int = ...,
    bootstrap: int = ...,
    gamma: Literal["fit", "mean", "max"] = ...,
    pca_center: Literal["centroid", "point"] = ...,
    seed: int = ...,
    threads: int = ...,
    test_sample: Optional[Points] = ...,
    output: Optional[PathLike] = ...,
    tile_points: Optional[int] = ...,
    progress: Progress = ...,
) -> Tuple[Optional[Dict[str, npt.NDArray[np.float64]]], Dict[str, Any]]: ...
def normals(
    points: Points,
    *,
    neighbors: int = ...,
    fit: Literal["pca", "poly"] = ...,
    degree: int = ...,
    pca_center: Literal["centroid", "point"] = ...,
    bootstrap: int = ...,
    seed: int = ...,
    threads: int = ...,
    test_error: bool = ...,
    k_ref: int = ...,
    select_k: Optional[Union[str, Sequence[int]]] = ...,
    select_rule: Literal["test-error", "mse", "auto"] = ...,
    noise_k: int = ...,
    noise_pool: Literal["global", "local"] = ...,
    select_degree: Optional[Sequence[int]] = ...,
    curve: bool = ...,
    truth: Optional[Points] = ...,
    smooth_iterations: int = ...,
    alpha: float = ...,
    sigma_d: float = ...,
    sigma_nu: Union[float, Literal["auto", "inf"]] = ...,
    orient: Literal["none", "mst"] = ...,
    output: Optional[PathLike] = ...,
    tile_points: Optional[int] = ...,
    progress: Progress = ...,
) -> Tuple[Optional[Dict[str, np.ndarray]], Dict[str, Any]]: ...
def generate(
    shape: Literal["sphere", "cube", "torus", "plane"],
    *,
    points: int = ...,
    sampling: Literal["regular", "random"] = ...,
    seed: int = ...,
    feature_width: float = ...,
) -> Cloud: ...
def noise(
    points: Points,
    normals: Optional[ArrayLike] = ...,
    *,
    level: float = ...,
    sigma_diag: Optional[float] = ...,
    model: Literal["gaussian", "uniform"] = ...,
    seed: int = ...,
    threads: int = ...,
    progress: Progress = ...,
) -> npt.NDArray[np.float64]: ...
def sample(
    mesh: Union[Mapping[str, ArrayLike], PathLike],
    *,
    points: int = ...,
    sharp_angle: float = ...,
    feature_width: float = ...,
    seed: int = ...,
    threads: int = ...,
) -> Cloud: ...
def evaluate(
    normals: Optional[ArrayLike] = ...,
    true_normals: Optional[ArrayLike] = ...,
    *,
    feature: Optional[ArrayLike] = ...,
    true_feature: Optional[ArrayLike] = ...,
    split: Optional[ArrayLike] = ...,
    split_q: float = ...,
    points: Optional[Points] = ...,
    truth: Optional[Union[Mapping[str, Any], PathLike]] = ...,
    surface: Optional[Union[Mapping[str, Any], PathLike]] = ...,
    threads: int = ...,
    progress: Progress = ...,
) -> Dict[str, Any]: ...
def render(
    points: Points,
    *,
    output: Optional[PathLike] = ...,
    normals: Optional[ArrayLike] = ...,
    field: Optional[Union[str, ArrayLike]] = ...,
    colormap: Literal["viridis", "magma", "gray", "coolwarm"] = ...,
    range: Optional[Tuple[float, float]] = ...,
    view: Optional[Literal["front", "back", "left", "right", "top", "bottom", "iso"]] = ...,
    azimuth: Optional[float] = ...,
    elevation: Optional[float] = ...,
    up: Literal["x", "y", "z", "auto"] = ...,
    views: Literal[1, 4] = ...,
    size: Tuple[int, int] = ...,
    point_size: float = ...,
    title: Optional[str] = ...,
    flat: bool = ...,
    square: bool = ...,
    threads: int = ...,
    progress: Progress = ...,
) -> Optional[npt.NDArray[np.uint8]]: ...
Length = Union[float, str]

def smooth(
    points: Points,
    *,
    method: Literal["naive", "bilateral", "multipass", "auto"] = ...,
    neighbors: int = ...,
    degree: int = ...,
    bootstrap: int = ...,
    gamma: Literal["fit", "mean", "max"] = ...,
    pca_center: Literal["centroid", "point"] = ...,
    estimator: Literal["auto", "632", "632plus"] = ...,
    threshold: Length = ...,
    h1: Length = ...,
    h2: Length = ...,
    order: Literal["parallel", "sequential"] = ...,
    a: float = ...,
    iterations: int = ...,
    k_min: int = ...,
    k_error: Length = ...,
    guard: Literal["on", "off"] = ...,
    degree_test: Literal["auto", "on", "off"] = ...,
    k_max: int = ...,
    seed: int = ...,
    threads: int = ...,
    output: Optional[PathLike] = ...,
    tile_points: Optional[int] = ...,
    progress: Progress = ...,
) -> Tuple[
    Optional[npt.NDArray[np.float64]], Optional[Dict[str, np.ndarray]], Dict[str, Any]
]: ...
def features(
    points: Points,
    *,
    method: Literal["distance", "variance"] = ...,
    neighbors: int = ...,
    bootstrap: int = ...,
    k_min: int = ...,
    k_max: int = ...,
    k_step: int = ...,
    ratio_threshold: float = ...,
    noise_factor: float = ...,
    derivative: float = ...,
    alpha: float = ...,
    iterations: int = ...,
    filter_k: int = ...,
    sigma_range: float = ...,
    threshold: Union[float, Literal["auto"]] = ...,
    tail_rule: Literal["null", "otsu", "mad"] = ...,
    false_positive_rate: float = ...,
    variance_filter_k: int = ...,
    feature_angle: float = ...,
    variance_k_max: int = ...,
    seed: int = ...,
    threads: int = ...,
    output: Optional[PathLike] = ...,
    tile_points: Optional[int] = ...,
    progress: Progress = ...,
) -> Tuple[Optional[Dict[str, np.ndarray]], Dict[str, Any]]: ...
