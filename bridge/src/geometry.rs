//! Geometry classes: `Pose`, `Detector`, `Geometry` (cone or parallel set-up) and `View`
//! (the general form: source or beam direction, centre of pixel (0, 0), pixel steps).

use crate::errors;
use crate::volume::{PyVolume, vec3};
use glam::DVec3;
use numpy::{IntoPyArray, PyArray2, PyArray3};
use pyo3::prelude::*;
use tomograf_sim::geometry::angles;
use tomograf_sim::{Beam, Detector, Geometry, Pose, View, ViewBeam};

/// Source pose around the isocentre, in degrees.
///
/// ``theta_deg`` (θ): gantry angle about the patient's superior axis (+z, LPS); θ = 0 is
/// AP (source anterior, at −y), θ = 90 puts the source at the patient's left (+x).
/// ``phi_deg`` (φ): elevation towards the head (+z).
#[pyclass(module = "tomograf", name = "Pose", frozen, from_py_object, eq)]
#[derive(Clone, Copy, PartialEq)]
pub struct PyPose {
    pub(crate) inner: Pose,
}

#[pymethods]
impl PyPose {
    #[new]
    #[pyo3(signature = (theta_deg, phi_deg=0.0))]
    fn new(theta_deg: f64, phi_deg: f64) -> Self {
        Self {
            inner: Pose::new(theta_deg, phi_deg),
        }
    }
    /// A named view (``ap``, ``pa``, ``lateral``/``lat``/``left-lateral``,
    /// ``right-lateral``) or ``"θ"`` / ``"θ,φ"`` in degrees.
    #[staticmethod]
    fn parse(text: &str) -> PyResult<Self> {
        Ok(Self {
            inner: angles::parse_pose(text).map_err(errors::sim)?,
        })
    }
    /// Gantry angle θ, degrees.
    #[getter]
    fn theta_deg(&self) -> f64 {
        self.inner.theta_deg
    }
    /// Elevation φ, degrees.
    #[getter]
    fn phi_deg(&self) -> f64 {
        self.inner.phi_deg
    }
    fn __repr__(&self) -> String {
        format!(
            "Pose(theta_deg={}, phi_deg={})",
            self.inner.theta_deg, self.inner.phi_deg
        )
    }
}

/// ``count`` poses from θ = ``start_deg`` every ``step_deg`` at elevation ``phi_deg``
/// (``arc(0, 5, 72)``: 72 views every 5°).
#[pyfunction]
#[pyo3(signature = (start_deg, step_deg, count, phi_deg=0.0))]
pub fn arc(start_deg: f64, step_deg: f64, count: usize, phi_deg: f64) -> PyResult<Vec<PyPose>> {
    Ok(angles::arc(start_deg, step_deg, count, phi_deg)
        .map_err(errors::sim)?
        .into_iter()
        .map(|inner| PyPose { inner })
        .collect())
}

/// A flat panel of ``rows × cols`` pixels. Pixel (0, 0) is the top-left pixel seen from
/// the source (beam's-eye view); columns run right, rows down.
///
/// ``pitch_mm``: centre-to-centre pixel distance at the detector (mm); ``pitch_v_mm``:
/// a different row pitch (default: same). ``offset_u_mm``/``offset_v_mm``: shift of the
/// panel centre along columns (right) / rows (down), mm.
#[pyclass(module = "tomograf", name = "Detector", frozen, from_py_object)]
#[derive(Clone, Copy)]
pub struct PyDetector {
    pub(crate) inner: Detector,
}

#[pymethods]
impl PyDetector {
    #[new]
    #[pyo3(signature = (rows, cols, pitch_mm, pitch_v_mm=None, offset_u_mm=0.0, offset_v_mm=0.0))]
    fn new(
        rows: usize,
        cols: usize,
        pitch_mm: f64,
        pitch_v_mm: Option<f64>,
        offset_u_mm: f64,
        offset_v_mm: f64,
    ) -> PyResult<Self> {
        let inner = Detector {
            rows,
            cols,
            pitch_u_mm: pitch_mm,
            pitch_v_mm: pitch_v_mm.unwrap_or(pitch_mm),
            offset_u_mm,
            offset_v_mm,
        };
        inner.validate().map_err(errors::sim)?;
        Ok(Self { inner })
    }
    #[getter]
    fn rows(&self) -> usize {
        self.inner.rows
    }
    #[getter]
    fn cols(&self) -> usize {
        self.inner.cols
    }
    /// (column pitch, row pitch), mm.
    #[getter]
    fn pitch_mm(&self) -> (f64, f64) {
        (self.inner.pitch_u_mm, self.inner.pitch_v_mm)
    }
    fn __repr__(&self) -> String {
        let d = &self.inner;
        format!(
            "Detector(rows={}, cols={}, pitch_mm=({}, {}), offset_mm=({}, {}))",
            d.rows, d.cols, d.pitch_u_mm, d.pitch_v_mm, d.offset_u_mm, d.offset_v_mm
        )
    }
}

/// An acquisition set-up: beam (cone with SAD/SID, or parallel), detector and isocentre
/// (world LPS mm). Build with :meth:`Geometry.cone` or :meth:`Geometry.parallel`.
#[pyclass(module = "tomograf", name = "Geometry", frozen)]
#[derive(Clone, Copy)]
pub struct PyGeometry {
    pub(crate) inner: Geometry,
}

/// A pose given as a `Pose` or as θ in degrees.
fn pose_of(obj: &Bound<'_, PyAny>) -> PyResult<Pose> {
    if let Ok(p) = obj.cast::<PyPose>() {
        return Ok(p.get().inner);
    }
    if let Ok(t) = obj.extract::<f64>() {
        return Ok(Pose::new(t, 0.0));
    }
    if let Ok(s) = obj.extract::<String>() {
        return angles::parse_pose(&s).map_err(errors::sim);
    }
    Err(errors::value(
        "a pose must be a tomograf.Pose, θ in degrees, or a name such as 'ap'",
    ))
}

#[pymethods]
impl PyGeometry {
    /// Flat-panel cone beam: source at ``sad_mm`` from the isocentre, detector at
    /// ``sid_mm`` from the source (SID ≥ SAD).
    #[staticmethod]
    #[pyo3(signature = (sad_mm, sid_mm, detector, isocentre=[0.0, 0.0, 0.0]))]
    fn cone(sad_mm: f64, sid_mm: f64, detector: PyDetector, isocentre: [f64; 3]) -> PyResult<Self> {
        let inner = Geometry {
            beam: Beam::Cone { sad_mm, sid_mm },
            detector: detector.inner,
            isocentre: vec3("isocentre", isocentre)?,
        };
        inner.validate().map_err(errors::sim)?;
        Ok(Self { inner })
    }
    /// Parallel beam; the detector plane passes through the isocentre and the pitch is
    /// measured there.
    #[staticmethod]
    #[pyo3(signature = (detector, isocentre=[0.0, 0.0, 0.0]))]
    fn parallel(detector: PyDetector, isocentre: [f64; 3]) -> PyResult<Self> {
        let inner = Geometry {
            beam: Beam::Parallel,
            detector: detector.inner,
            isocentre: vec3("isocentre", isocentre)?,
        };
        inner.validate().map_err(errors::sim)?;
        Ok(Self { inner })
    }
    /// The view for one pose (a ``Pose``, θ in degrees, or a name such as ``"ap"``).
    fn view(&self, pose: &Bound<'_, PyAny>) -> PyResult<PyView> {
        Ok(PyView {
            inner: self.inner.view(pose_of(pose)?).map_err(errors::sim)?,
        })
    }
    /// Views for a list of poses.
    fn views(&self, poses: Vec<Bound<'_, PyAny>>) -> PyResult<Vec<PyView>> {
        poses.iter().map(|p| self.view(p)).collect()
    }
    /// The square pixel pitch (mm) at which ``volume`` fits on the panel in every pose
    /// (2 % margin); this geometry's own pitch is ignored.
    fn fit_pitch(&self, poses: Vec<Bound<'_, PyAny>>, volume: &PyVolume) -> PyResult<f64> {
        let poses = poses.iter().map(pose_of).collect::<PyResult<Vec<_>>>()?;
        self.inner
            .fit_pitch(&poses, &volume.inner)
            .map_err(errors::sim)
    }
    /// ``"cone"`` or ``"parallel"``.
    #[getter]
    fn beam(&self) -> &'static str {
        match self.inner.beam {
            Beam::Cone { .. } => "cone",
            Beam::Parallel => "parallel",
        }
    }
    #[getter]
    fn detector(&self) -> PyDetector {
        PyDetector {
            inner: self.inner.detector,
        }
    }
    /// Isocentre, world LPS mm.
    #[getter]
    fn isocentre(&self) -> (f64, f64, f64) {
        self.inner.isocentre.into()
    }
    fn __repr__(&self) -> String {
        match self.inner.beam {
            Beam::Cone { sad_mm, sid_mm } => {
                format!("Geometry.cone(sad_mm={sad_mm}, sid_mm={sid_mm}, ...)")
            }
            Beam::Parallel => "Geometry.parallel(...)".into(),
        }
    }
}

/// One projection view in the general form (any calibrated flat-panel geometry).
///
/// Pixel (r, c) has its centre at ``detector_origin + c·u + r·v`` (world LPS mm).
/// Cone beam: rays run from ``source`` to each pixel centre. Parallel beam: whole lines
/// along the unit ``direction`` through each pixel centre.
#[pyclass(module = "tomograf", name = "View", frozen, from_py_object)]
#[derive(Clone, Copy)]
pub struct PyView {
    pub(crate) inner: View,
}

impl PyView {
    fn checked(inner: View) -> PyResult<Self> {
        inner.validate().map_err(errors::sim)?;
        Ok(Self { inner })
    }
}

#[pymethods]
impl PyView {
    /// A cone-beam view from the source position, the centre of pixel (0, 0) and the
    /// column/row steps ``u``/``v`` (all world LPS mm).
    #[staticmethod]
    fn cone(
        source: [f64; 3],
        detector_origin: [f64; 3],
        u: [f64; 3],
        v: [f64; 3],
        rows: usize,
        cols: usize,
    ) -> PyResult<Self> {
        Self::checked(View {
            beam: ViewBeam::Cone {
                source: vec3("source", source)?,
            },
            detector_origin: vec3("detector origin", detector_origin)?,
            u: vec3("column step u", u)?,
            v: vec3("row step v", v)?,
            rows,
            cols,
        })
    }
    /// A parallel-beam view along ``direction`` (normalised here; source → detector).
    #[staticmethod]
    fn parallel(
        direction: [f64; 3],
        detector_origin: [f64; 3],
        u: [f64; 3],
        v: [f64; 3],
        rows: usize,
        cols: usize,
    ) -> PyResult<Self> {
        let d = vec3("parallel beam direction", direction)?;
        if d.length() == 0.0 {
            return Err(errors::value("parallel beam direction is the zero vector"));
        }
        Self::checked(View {
            beam: ViewBeam::Parallel {
                direction: d.normalize(),
            },
            detector_origin: vec3("detector origin", detector_origin)?,
            u: vec3("column step u", u)?,
            v: vec3("row step v", v)?,
            rows,
            cols,
        })
    }
    /// ``"cone"`` or ``"parallel"``.
    #[getter]
    fn beam(&self) -> &'static str {
        match self.inner.beam {
            ViewBeam::Cone { .. } => "cone",
            ViewBeam::Parallel { .. } => "parallel",
        }
    }
    /// Source position (cone beam), world LPS mm; ``None`` for parallel beam.
    #[getter]
    fn source(&self) -> Option<(f64, f64, f64)> {
        match self.inner.beam {
            ViewBeam::Cone { source } => Some(source.into()),
            ViewBeam::Parallel { .. } => None,
        }
    }
    /// Unit beam direction (parallel beam); ``None`` for cone beam.
    #[getter]
    fn direction(&self) -> Option<(f64, f64, f64)> {
        match self.inner.beam {
            ViewBeam::Cone { .. } => None,
            ViewBeam::Parallel { direction } => Some(direction.into()),
        }
    }
    /// Centre of pixel (0, 0), world LPS mm.
    #[getter]
    fn detector_origin(&self) -> (f64, f64, f64) {
        self.inner.detector_origin.into()
    }
    /// Step from one column to the next, world mm.
    #[getter]
    fn u(&self) -> (f64, f64, f64) {
        self.inner.u.into()
    }
    /// Step from one row to the next, world mm.
    #[getter]
    fn v(&self) -> (f64, f64, f64) {
        self.inner.v.into()
    }
    #[getter]
    fn rows(&self) -> usize {
        self.inner.rows
    }
    #[getter]
    fn cols(&self) -> usize {
        self.inner.cols
    }
    /// World position (mm) of the centre of pixel (row, col); fractions allowed.
    fn pixel_centre(&self, row: f64, col: f64) -> (f64, f64, f64) {
        self.inner.pixel_centre(row, col).into()
    }
    /// Continuous (row, col) where the line from the source (or along the beam) through
    /// world point ``p`` (mm) meets the detector; ``None`` if it never does.
    fn project_point(&self, p: [f64; 3]) -> Option<(f64, f64)> {
        self.inner.project_point(DVec3::from(p))
    }
    /// The ray of every pixel centre: ``(origin, direction, t_min, t_max)`` with arrays
    /// of shape ``(rows, cols, 3)``, ``(rows, cols, 3)``, ``(rows, cols)``,
    /// ``(rows, cols)`` (float64). A ray is ``origin + t·direction`` for t in
    /// [t_min, t_max] mm, ``direction`` a unit vector. Cone beam: origin = source,
    /// t from 0 to the pixel centre. Parallel beam: origin = pixel centre, t from −∞ to ∞.
    #[allow(clippy::type_complexity)]
    fn rays<'py>(
        &self,
        py: Python<'py>,
    ) -> (
        Bound<'py, PyArray3<f64>>,
        Bound<'py, PyArray3<f64>>,
        Bound<'py, PyArray2<f64>>,
        Bound<'py, PyArray2<f64>>,
    ) {
        let (rows, cols) = (self.inner.rows, self.inner.cols);
        let mut o = ndarray::Array3::zeros((rows, cols, 3));
        let mut d = ndarray::Array3::zeros((rows, cols, 3));
        let mut t0 = ndarray::Array2::zeros((rows, cols));
        let mut t1 = ndarray::Array2::zeros((rows, cols));
        for r in 0..rows {
            for c in 0..cols {
                let ray = self.inner.ray(r as f64, c as f64);
                for a in 0..3 {
                    o[(r, c, a)] = ray.origin[a];
                    d[(r, c, a)] = ray.direction[a];
                }
                t0[(r, c)] = ray.t_min;
                t1[(r, c)] = ray.t_max;
            }
        }
        (
            o.into_pyarray(py),
            d.into_pyarray(py),
            t0.into_pyarray(py),
            t1.into_pyarray(py),
        )
    }
    fn __repr__(&self) -> String {
        format!(
            "View({}, rows={}, cols={}, detector_origin={}, u={}, v={})",
            self.beam(),
            self.inner.rows,
            self.inner.cols,
            self.inner.detector_origin,
            self.inner.u,
            self.inner.v
        )
    }
}
