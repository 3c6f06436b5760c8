"""Simulated X-ray projections (DRRs) of CT volumes: exact Siddon and trilinear ray tracing.

Units: lengths mm, attenuation mm⁻¹, energies keV, CT values HU, angles degrees.
World frame: DICOM LPS (+x patient left, +y posterior, +z head). Volumes are numpy
``[k, j, i]`` (z, y, x for an axial CT; i fastest). Images are ``(rows, cols)``, row 0
at the top in the beam's-eye view. Errors: ``ValueError`` for bad input,
``OSError`` (``FileNotFoundError``, ``PermissionError``) for files.
"""

from os import PathLike
from typing import Any, Callable, Dict, List, Literal, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

Vec3 = Tuple[float, float, float]
Projector = Literal["siddon", "trilinear"]
QuantityName = Literal["line-integral", "line_integral", "transmission", "intensity"]
TracerName = Literal["auto", "scalar", "packets", "sheets", "columns"]

class Volume:
    """A scalar field on a regular grid in the LPS world frame (HU, or mm⁻¹ after to_mu).

    Voxel (i, j, k) is centred at ``origin + direction @ (spacing * (i, j, k))``."""

    def __init__(
        self,
        array: npt.ArrayLike,
        spacing: Sequence[float],
        origin: Optional[Sequence[float]] = None,
        direction: Optional[npt.ArrayLike] = None,
    ) -> None:
        """From a 3-D array ``[k, j, i]`` (→ float32). spacing (sx, sy, sz) mm along (i, j, k);
        origin: world LPS mm of voxel (0, 0, 0)'s centre (default: grid centred on 0);
        direction: 3×3, columns = world directions of (i, j, k) (default identity)."""
    @staticmethod
    def load(path: Union[str, PathLike[str]], allow_non_ct: bool = False) -> Volume:
        """NIfTI file (.nii/.nii.gz, RAS→LPS) or a folder with one DICOM CT series."""
    def save_nifti(self, path: Union[str, PathLike[str]]) -> None:
        """Write NIfTI-1 (.nii/.nii.gz) atomically."""
    @property
    def array(self) -> npt.NDArray[np.float32]:
        """Copy of the voxels, shape (nk, nj, ni)."""
    @property
    def dims(self) -> Tuple[int, int, int]:
        """Voxels along (i, j, k)."""
    @property
    def shape(self) -> Tuple[int, int, int]:
        """(nk, nj, ni), the shape of ``array``."""
    @property
    def spacing(self) -> Vec3:
        """Voxel size along (i, j, k), mm."""
    @property
    def origin(self) -> Vec3:
        """World LPS mm of the centre of voxel (0, 0, 0)."""
    @property
    def direction(self) -> npt.NDArray[np.float64]:
        """3×3; column a = world direction of index axis a."""
    @property
    def centre(self) -> Vec3:
        """World LPS mm of the grid centre."""
    def index_to_world(self, ijk: Sequence[float]) -> Vec3: ...
    def world_to_index(self, p: Sequence[float]) -> Vec3: ...
    def min_max(self) -> Tuple[float, float]: ...
    def to_mu(
        self, energy_kev: Optional[float] = None, mu_water_per_mm: Optional[float] = None
    ) -> Volume:
        """HU → mm⁻¹: mu_water·max(0, 1 + HU/1000); default 60 keV."""

def mu_water(energy_kev: float) -> float:
    """Linear attenuation of water, mm⁻¹ (xraydb / Elam 2002)."""

def water_energy_range_kev() -> Tuple[float, float]: ...

class Pose:
    """θ: gantry angle about +z (0 = AP, source anterior; 90 = source at patient's left);
    φ: elevation towards the head. Degrees."""

    def __init__(self, theta_deg: float, phi_deg: float = 0.0) -> None: ...
    @staticmethod
    def parse(text: str) -> Pose:
        """'ap', 'pa', 'lateral', 'right-lateral', or 'θ' / 'θ,φ'."""
    @property
    def theta_deg(self) -> float: ...
    @property
    def phi_deg(self) -> float: ...

PoseLike = Union[Pose, float, str]

def arc(start_deg: float, step_deg: float, count: int, phi_deg: float = 0.0) -> list[Pose]: ...

class Detector:
    """rows × cols flat panel; pixel (0, 0) top-left in beam's-eye view; pitch in mm at the
    detector; offsets shift the panel centre along columns (right) / rows (down), mm."""

    def __init__(
        self,
        rows: int,
        cols: int,
        pitch_mm: float,
        pitch_v_mm: Optional[float] = None,
        offset_u_mm: float = 0.0,
        offset_v_mm: float = 0.0,
    ) -> None: ...
    @property
    def rows(self) -> int: ...
    @property
    def cols(self) -> int: ...
    @property
    def pitch_mm(self) -> Tuple[float, float]:
        """(column pitch, row pitch), mm."""

class Geometry:
    """Beam (cone: SAD/SID mm; or parallel), detector and isocentre (world LPS mm)."""

    @staticmethod
    def cone(sad_mm: float, sid_mm: float, detector: Detector, isocentre: Sequence[float] = (0.0, 0.0, 0.0)) -> Geometry: ...
    @staticmethod
    def parallel(detector: Detector, isocentre: Sequence[float] = (0.0, 0.0, 0.0)) -> Geometry: ...
    def view(self, pose: PoseLike) -> View: ...
    def views(self, poses: Sequence[PoseLike]) -> list[View]: ...
    def fit_pitch(self, poses: Sequence[PoseLike], volume: Volume) -> float:
        """Square pitch (mm) that fits the volume on the panel in every pose (2 % margin)."""
    @property
    def beam(self) -> Literal["cone", "parallel"]: ...
    @property
    def detector(self) -> Detector: ...
    @property
    def isocentre(self) -> Vec3: ...

class View:
    """General form: pixel (r, c) centre = detector_origin + c·u + r·v (world LPS mm)."""

    @staticmethod
    def cone(source: Sequence[float], detector_origin: Sequence[float], u: Sequence[float],
             v: Sequence[float], rows: int, cols: int) -> View: ...
    @staticmethod
    def parallel(direction: Sequence[float], detector_origin: Sequence[float], u: Sequence[float],
                 v: Sequence[float], rows: int, cols: int) -> View: ...
    @property
    def beam(self) -> Literal["cone", "parallel"]: ...
    @property
    def source(self) -> Optional[Vec3]: ...
    @property
    def direction(self) -> Optional[Vec3]: ...
    @property
    def detector_origin(self) -> Vec3: ...
    @property
    def u(self) -> Vec3: ...
    @property
    def v(self) -> Vec3: ...
    @property
    def rows(self) -> int: ...
    @property
    def cols(self) -> int: ...
    def pixel_centre(self, row: float, col: float) -> Vec3: ...
    def project_point(self, p: Sequence[float]) -> Optional[Tuple[float, float]]: ...
    def rays(self) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64],
                            npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """(origin (r,c,3), unit direction (r,c,3), t_min (r,c), t_max (r,c)), mm."""

def project(
    mu: Volume,
    views: Union[View, Sequence[View]],
    projector: Projector = "siddon",
    step_voxels: float = 0.5,
    quantity: QuantityName = "line-integral",
    i0: float = 1.0,
    tracer: TracerName = "auto",
) -> npt.NDArray[np.float32]:
    """Render attenuation (mm⁻¹): (rows, cols) for one view, (n, rows, cols) for a list.
    ``tracer``: the exact Siddon tracer (images agree to rounding).
    GIL released; bit-identical for any thread count."""

def line_integrals(
    mu: Volume,
    origins: npt.ArrayLike,
    directions: npt.ArrayLike,
    t_min: Optional[npt.ArrayLike] = None,
    t_max: Optional[npt.ArrayLike] = None,
    projector: Projector = "siddon",
    step_voxels: float = 0.5,
) -> npt.NDArray[np.float64]:
    """∫mu ds along origin + t·direction (direction normalised), t ∈ [t_min, t_max] mm
    (defaults 0, ∞). origins/directions (..., 3) → result (...)."""

def thorax(
    dims: Sequence[int] = (256, 256, 133),
    spacing_mm: Sequence[float] = (1.4, 1.4, 2.5),
    centre: Sequence[float] = (0.0, 0.0, 0.0),
    seed: Optional[int] = None,
) -> Volume:
    """Analytic thorax phantom sampled at voxel centres (HU)."""

def thorax_line_integrals(view: View, mu_water_per_mm: float, seed: Optional[int] = None) -> npt.NDArray[np.float64]:
    """Exact line integrals of the continuous analytic thorax through each pixel centre."""

def chest(
    seed: int = 0,
    profile: Literal["lidc", "lidc-cropped", "full-chest"] = "lidc",
    dims: Sequence[int] = (256, 256, 133),
    spacing_mm: Sequence[float] = (1.4, 1.4, 2.5),
    table: bool = False,
    pacemaker: bool = False,
) -> Volume:
    """Procedural chest patient (HU), grid centred on the world origin."""

def describe_chest(
    seed: int = 0,
    profile: Literal["lidc", "lidc-cropped", "full-chest"] = "lidc",
    dims: Sequence[int] = (256, 256, 133),
    spacing_mm: Sequence[float] = (1.4, 1.4, 2.5),
    table: bool = False,
    pacemaker: bool = False,
) -> dict[str, Any]:
    """The sampled patient (sizes, landmarks, nodules; world LPS mm) without voxels."""

def presets() -> List[str]:
    """Acquisition preset names ("ideal-drr" is `project` itself)."""

def acquire(
    hu: Volume,
    views: Union[View, Sequence[View]],
    preset: str = "kv-flat-panel-120kvp",
    kvp: Optional[float] = None,
    mas: Optional[float] = None,
    energy_bins: Optional[int] = None,
    signal: Optional[str] = None,
    seed: int = 0,
    projector: Projector = "siddon",
    detector: Optional[str] = None,
) -> npt.NDArray[np.float32]:
    """Real detector physics on a CT in HU (polychromatic beam, tissues, detector noise,
    blur, flat-field, −log): (rows, cols) for one view, (n, rows, cols) for a list; a
    photon-counting detector adds a channel axis. ``detector`` replaces the preset's
    detector by name (`detector_models`). GIL released; seeded, thread-count
    independent."""

def dose(
    hu: Volume,
    views: Union[View, Sequence[View]],
    preset: str = "kv-flat-panel-120kvp",
    kvp: Optional[float] = None,
    mas: Optional[float] = None,
    photons: int = 1_000_000,
    seed: int = 0,
) -> Volume:
    """Absorbed dose in Gy (a Volume on the CT's grid) that the views deliver to a CT in HU
    with a preset's spectrum (kVp, mAs per view) and tissues: Monte Carlo, `photons`
    histories per view, each view's source collimated to its detector, electron energy
    deposited locally. Seeded; GIL released; thread-count independent."""

def detector_models() -> List[str]:
    """Detector model names: "perfect-absorber" (alias "ideal"), "noiseless-csi",
    "kv-flat-panel", "cbct", "photon-counting"."""

def scatter_matched(
    source: Sequence[float],
    detector_origin: Sequence[float],
    u: Sequence[float],
    v: Sequence[float],
    rows: int,
    cols: int,
    box_min: Sequence[float],
    box_max: Sequence[float],
    mu_t: float,
    albedo: float,
    g: float = 0.0,
    photons: int = 100000,
    max_order: int = 1000,
    seed: int = 0,
) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Matched-physics scatter (monoenergetic, homogeneous box of extinction mu_t mm⁻¹,
    constant albedo, Henyey–Greenstein phase g; 0 = isotropic) from a point source, scored
    by forced detection at every pixel centre detector_origin + c·u + r·v (mm): (single,
    multiple, single_se, total_se), each (rows, cols), photons per pixel per unit source
    intensity (photons/sr). GIL released; seeded, thread-count independent."""

def render_scene(scene: Union[str, "PathLike[str]", dict]) -> npt.NDArray[np.float32]:
    """Renders every view of a scene — a TOML scene file (relative paths from its folder) or
    a dict of the same tables (relative paths from the working directory; keys and units of
    docs/scene.md) — as `tomograf project --scene` does, to the same bytes: float32
    (views, rows, cols), the ideal DRR in the scene's output quantity or the detector's
    signal with real physics; a photon-counting detector adds a channel axis after the
    views axis. Output files are not written. UserWarning for geometry probably not meant
    and for starved or saturated pixels; ValueError for a bad scene, FileNotFoundError for
    a missing file."""

def project_scene(
    scene: Union[str, "PathLike[str]", dict],
    progress: Optional[Callable[[str, int, int, str], object]] = None,
) -> Dict[str, Any]:
    """Renders every view of a scene and writes its files exactly as `tomograf project
    --scene` does (the same library function): images in the ``[output]`` formats into its
    ``dir`` (default ``out``, prefix ``drr``), the ``.npy`` stack, separate scatter images,
    dose and the JSON sidecar. ``progress(stage, done, total, message)`` is called while it
    runs (stage ``"view"``); an exception it raises is re-raised at the end. Warnings (geometry
    probably not meant, clipped pixels) are raised as UserWarning; every line the command
    line would print (dose totals too) is in the returned ``notes``. Returns
    ``views``, ``rows``, ``cols``, ``render_seconds``, ``load_seconds``, ``files``,
    ``dir`` and ``notes``."""

def reconstruct(
    item: Union[str, "PathLike[str]"],
    checkpoint: Union[str, "PathLike[str]"],
    *,
    views: int = 1,
    poses: Optional[Sequence[str]] = None,
    iterations: Optional[int] = None,
    psnr_threshold: Optional[float] = None,
    refine: Optional[int] = None,
    tune: Optional[Literal["codes-and-generator", "codes"]] = None,
    seed: int = 0,
    backend: Optional[str] = None,
    scatter_correction: Literal["none", "prior", "oracle"] = "none",
    progress: Optional[Callable[[str, int, int, str], object]] = None,
) -> Dict[str, Any]:
    """Reconstructs a CT from 1–10 projections of a data-set item (made by `tomograf
    dataset` or make_item) with a checkpoint written by `tomograf train`, as `tomograf
    reconstruct` does. ``views``: the paper's view sets (1 = AP, 2 = AP + lateral, 5 = every
    72°, 10 = every 36°); ``poses`` (``["ap", "lateral"]``, ``["0", "45,10"]``: θ or θ,φ in
    degrees) instead. The other keywords override the checkpoint's inference settings.
    ``progress(stage, done, total, message)`` is called per iteration. Returns ``volume``
    (a Volume in HU on the item's CT grid), ``spread`` (where the checkpoint averages
    several fits for this view count, each voxel's standard deviation across them: a Volume
    in HU; else None), ``iterations``, ``psnr_db`` (per input view), ``blend`` (where the
    checkpoint blended SART-TV from the mean in: ``{"weight": W, "views_psnr_db": dB}``,
    the views' mean projection PSNR before the blend that chose W; else None) and ``notes``
    (the lines the command line prints)."""

def evaluate(
    data: Union[str, "PathLike[str]"],
    output: Union[str, "PathLike[str]"],
    *,
    checkpoint: Optional[Union[str, "PathLike[str]"]] = None,
    views: Sequence[int] = (1, 2, 5, 10),
    train_data: Optional[Union[str, "PathLike[str]"]] = None,
    split: Optional[str] = None,
    items: Optional[int] = None,
    classical: bool = True,
    iterations: Optional[int] = None,
    psnr_threshold: Optional[float] = None,
    refine: Optional[int] = None,
    tune: Optional[Literal["codes-and-generator", "codes"]] = None,
    seed: int = 0,
    backend: Optional[str] = None,
    scatter_correction: Literal["none", "prior", "oracle"] = "none",
    pca_noise: float = ...,
    progress: Optional[Callable[[str, int, int, str], object]] = None,
) -> Dict[str, Any]:
    """Scores TomoGRAF (with ``checkpoint``) and the baselines — mean training volume,
    PCA-MAP (with ``train_data``), FDK and SART-TV (``classical``) — on a test data set, per
    item and view count, as `tomograf evaluate` does; files go to ``output`` and items
    already scored there are skipped. Returns ``markdown`` (the results table), ``notes``
    and ``rows``
    (per item, view count and method: ``item``, ``views``, ``method``, ``psnr_db``,
    ``ssim``, ``rmse_hu``, ``body_psnr_db``, ``body_ssim``, ``body_rmse_hu``,
    ``iterations``, ``seconds``)."""

def make_item(
    output: Union[str, "PathLike[str]"],
    *,
    ct: Optional[Union[str, "PathLike[str]"]] = None,
    phantom_seed: Optional[int] = None,
    profile: str = "lidc",
    table: bool = False,
    pacemaker: bool = False,
    index: int = 0,
    views: int = 72,
    size: int = 128,
    hu_window: Tuple[float, float] = (-1024.0, 2048.0),
    crop_hu: float = -900.0,
    energy_kev: float = 60.0,
    sad_mm: float = 1000.0,
    sid_mm: float = 1500.0,
    split: str = "train",
    physics: Optional[dict] = None,
    keep_table: bool = False,
    heterogeneity_hu: float = 0.0,
    organ_spread: float = 1.0,
    deform_mm: float = 0.0,
    augment_seed: Optional[int] = None,
    scan_range_seed: Optional[int] = None,
) -> "PathLike[str]":
    """Makes one TomoGRAF data-set item in the folder `output`, the same files (and bytes)
    as item `index` of `tomograf dataset`: ct.nii.gz (cropped CT resampled to size³, [0, 1]
    over hu_window in HU), projections.npy (float32 (views + 2, size, size): every
    360/views degrees, then AP and lateral, exact Siddon; line integrals at energy_kev keV,
    or the detector's signal when `physics` holds a scene's physics tables such as
    {"acquisition": {"preset": "kv-flat-panel-120kvp", "seed": 5}}), views.json and
    item.json (written last). Source: exactly one of `ct` (NIfTI or DICOM folder) and
    `phantom_seed` (profile "lidc" or "full-chest"). A CT is brought into the patient frame
    (i left, j posterior, k superior) and reduced to its body (couch, padding and stray
    voxels set to air) unless `keep_table`. `heterogeneity_hu`: a phantom's soft tissue given a correlated
    texture of that standard deviation (HU), as `tomograf dataset --heterogeneity`;
    `organ_spread`: its heart and diaphragm drawn from ranges that many times as wide, as
    `tomograf dataset --organ-spread` (1: as drawn); `deform_mm`: it warped by a smooth
    random displacement field of that standard deviation, as `tomograf dataset --deform`;
    `augment_seed`, `scan_range_seed`: its shape augmentation and scan range drawn from
    that seed and `index`, as `tomograf dataset --augment` and `--scan-range`.
    Distances in mm. Returns the folder.
    ValueError for bad settings, FileNotFoundError for a missing CT."""
