"""Type stubs of meshmatch: example-based texturing of 3D meshes. Defaults are the CLI's."""

from os import PathLike
from typing import Any, Callable, Literal, Sequence, TypedDict, Union

import numpy as np
import numpy.typing as npt

__version__: str

ArrayLike = npt.ArrayLike
StrPath = Union[str, PathLike[str]]
Progress = Callable[[float, str], Any]
"""Called on the calling thread with (fraction done in [0, 1], stage name); raising stops the call."""
Mask = Union[Sequence[bool], Sequence[int], npt.NDArray[Any]]
"""One boolean per vertex, or vertex indices."""
Pairs = Union[StrPath, Sequence[tuple[int, int]], Sequence[tuple[int, Sequence[int]]], npt.NDArray[Any]]
"""A correspondences JSON file, or (source_vertex, target_vertex) / (source_vertex, [targets]) pairs."""

class MeshMatchError(Exception):
    """A call was refused or failed; the message is the CLI's one line."""

class Cancelled(MeshMatchError):
    """A call was stopped through its CancelToken."""

class CancelToken:
    """Stops a running call when `cancel()` is called from another thread."""

    def __init__(self) -> None: ...
    def cancel(self) -> None: ...
    @property
    def cancelled(self) -> bool: ...

class Mesh:
    """A triangle mesh with optional per-vertex sRGB colours, per-corner UVs and a texture."""

    def __init__(
        self,
        vertices: ArrayLike,
        faces: ArrayLike,
        colors: ArrayLike | None = None,
        uvs: ArrayLike | None = None,
        texture: ArrayLike | None = None,
    ) -> None:
        """vertices (N, 3); faces (F, 3) vertex indices; colors (N, 3) or (N, 4) floats in [0, 1]
        or uint8; uvs (3F, 2) or (F, 3, 2) per face corner, or (N, 2) per vertex (V up);
        texture (H, W, 3 or 4) uint8 (or floats in [0, 1]), row 0 at the top; needs uvs."""
    @property
    def vertices(self) -> npt.NDArray[np.float32]: ...
    @property
    def faces(self) -> npt.NDArray[np.int32]: ...
    @property
    def colors(self) -> npt.NDArray[np.float32] | None: ...
    @property
    def uvs(self) -> npt.NDArray[np.float32] | None:
        """(3F, 2): corner k of face f is row 3f + k."""
    @property
    def normals(self) -> npt.NDArray[np.float32] | None: ...
    @property
    def texture(self) -> npt.NDArray[np.uint8] | None:
        """(H, W, 3) sRGB, row 0 at the top."""
    @property
    def file_index(self) -> npt.NDArray[np.int64]:
        """Per vertex, its index in the file it was loaded from."""
    @property
    def num_vertices(self) -> int: ...
    @property
    def num_faces(self) -> int: ...
    def with_colors(self, colors: ArrayLike | None) -> Mesh: ...
    def save(self, path: StrPath) -> None:
        """Write by extension: .ply, .glb, .gltf, .obj (+ .mtl + PNG)."""

def load(path: StrPath) -> Mesh:
    """Load .obj, .ply, .glb or .gltf as the CLI does (checked and repaired)."""

def transfer(
    source: Mesh,
    target: Mesh,
    correspondences: Pairs | None = None,
    *,
    vertices: int = 64000,
    levels: int | None = None,
    iterations: int = 5,
    tolerance: float = 0.005,
    seed: int = 0,
    shape_weight: float = 1.0,
    fine_shape_scale: float = 1.0,
    sharpen: bool = True,
    structure: float | Literal["auto"] | None = None,
    texture_size: int | None = None,
    textured: bool | None = None,
    working_resolution: bool = False,
    progress: Progress | None = None,
    cancel: CancelToken | None = None,
) -> Mesh:
    """MeshMatch transfer: the target with colours per vertex, and a texture when it has UVs
    (or textured=True). structure None = auto."""

def complete(
    mesh: Mesh,
    mask: Mask | None = None,
    *,
    painted: Mesh | None = None,
    clay: tuple[int, int, int] | None = None,
    vertices: int = 64000,
    levels: int | None = None,
    iterations: int = 5,
    tolerance: float = 0.005,
    seed: int = 0,
    shape_weight: float = 1.0,
    sharpen: bool = True,
    texture_size: int | None = None,
    textured: bool | None = None,
    progress: Progress | None = None,
    cancel: CancelToken | None = None,
) -> Mesh:
    """Completion by example: synthesise the masked (or clay-coloured) vertices."""

def update(
    old: Mesh,
    new: Mesh,
    *,
    vertices: int = 64000,
    levels: int | None = None,
    iterations: int = 5,
    tolerance: float = 0.005,
    seed: int = 0,
    shape_weight: float = 1.0,
    sharpen: bool = True,
    texture_size: int | None = None,
    textured: bool | None = None,
    progress: Progress | None = None,
    cancel: CancelToken | None = None,
) -> Mesh:
    """Texture update after a geometry edit."""

def detail(
    source: Mesh,
    target: Mesh,
    *,
    strength: float = 1.0,
    vertices: int = 64000,
    levels: int | None = None,
    iterations: int = 5,
    tolerance: float = 0.005,
    seed: int = 0,
    shape_weight: float = 10.0,
    sharpen: bool = True,
    progress: Progress | None = None,
    cancel: CancelToken | None = None,
) -> Mesh:
    """Detail transfer: the target at the working resolution, displaced."""

def synthesize(
    exemplar: ArrayLike | StrPath,
    target: Mesh,
    *,
    texture_size: int = 2048,
    scale: float | None = None,
    exemplar_width: int | None = None,
    vertex_budget: int = 300000,
    orientation: Literal["auto", "random", "up", "relax2", "relax4", "features"] = "auto",
    levels: int = 4,
    mask: Mask | None = None,
    search: Literal["exhaustive", "fast"] = "fast",
    seed: int = 0,
    displace: bool = False,
    method: Literal["auto", "patches", "neighbourhood", "optimize"] = "auto",
    align_features: bool = False,
    feature_mask: ArrayLike | None = None,
    space: Literal["auto", "texture", "surface"] = "auto",
    texel_budget: int = 300000,
    output: Literal["texture", "dense"] = "texture",
    progress: Progress | None = None,
    cancel: CancelToken | None = None,
) -> Mesh:
    """Wei-Levoy synthesis from an exemplar image: the target with a baked texture, or the
    dense synthesized mesh (output="dense")."""

def weather(
    source: Mesh,
    target: Mesh,
    *,
    mask: Mask | None = None,
    method: Literal["parametric", "nonparametric"] = "parametric",
    up: Literal["y", "z"] = "y",
    vertices: int = 100000,
    rays: int = 64,
    clusters: int = 50,
    seed: int = 0,
    components: list[int] | None = None,
    mean: Literal["neighbours", "affine"] = "neighbours",
    texture_size: int = 1024,
    textured: bool | None = None,
    progress: Progress | None = None,
    cancel: CancelToken | None = None,
) -> Mesh:
    """Geometry-correlated transfer (Mertens et al. 2006); `components` keeps only those CCA
    components (0 = strongest), as `--components`; `mean` is the parametric method's mean
    colour, as `--mean` (`"affine"`: the paper's)."""

def quilt(
    base: Mesh,
    swatch: Literal["chain", "weave", "nuts", "studs", "scales"] | StrPath | Mesh = "chain",
    *,
    swatch_size: float | None = None,
    thickness: float | None = None,
    swatch_up: Literal["x", "y", "z"] = "z",
    seed: int = 1,
    merge: bool = False,
    nudge: bool = True,
    fill: bool = True,
    trim: bool = True,
    relink: bool = True,
    lattice: bool = True,
    progress: Progress | None = None,
    cancel: CancelToken | None = None,
) -> tuple[Mesh, npt.NDArray[np.int64]]:
    """Mesh quilting: (elements as one mesh, element id per vertex)."""

class Curve(TypedDict):
    points: npt.NDArray[np.float32]
    vertices: npt.NDArray[np.int64]
    kind: Literal["ridge", "ravine", "crease"]
    strength: float
    length: float
    closed: bool

def curves(
    mesh: Mesh,
    *,
    threshold: float = 1.0,
    min_length: float | None = None,
    crease_angle: float = 40.0,
    creases_only: bool = False,
    progress: Progress | None = None,
    cancel: CancelToken | None = None,
) -> list[Curve]:
    """Salient curves (crest lines and creases)."""

def features(
    mesh: Mesh,
    feature: str = "ao",
    *,
    up: Literal["y", "z"] = "y",
    rays: int = 64,
    seed: int = 0,
    progress: Progress | None = None,
    cancel: CancelToken | None = None,
) -> npt.NDArray[np.float32]:
    """One geometric feature per vertex: ao, height, curvature[:i], normal-x|y|z, occlusion-x|y|z."""

def feature_maps(
    mesh: Mesh,
    feature: str = "all",
    *,
    texture_size: int = 2048,
    radius: float = 0.01,
    cavity_radius: float = 0.003,
    up: Literal["y", "z"] = "y",
    rays: int = 64,
    seed: int = 0,
    new_atlas: bool = False,
    progress: Progress | None = None,
    cancel: CancelToken | None = None,
) -> dict[str, npt.NDArray[np.float32]]:
    """Baked feature maps (ao, curvature, cavity, thickness, normal, height) in the mesh's UVs or
    a generated atlas, gutters filled: name -> (size, size) or (size, size, 3) in [0, 1]."""

def bake(
    source: Mesh,
    target: Mesh,
    *,
    texture_size: int = 2048,
    new_atlas: bool = False,
    progress: Progress | None = None,
    cancel: CancelToken | None = None,
) -> Mesh:
    """Bake source's colours into a texture on target (same shape)."""
