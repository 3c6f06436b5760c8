//! `tomograf.Volume`: a CT or attenuation grid in the LPS world frame.

use crate::errors;
use glam::{DMat3, DVec3};
use numpy::{AllowTypeChange, IntoPyArray, PyArray2, PyArray3, PyArrayLike3};
use pyo3::prelude::*;
use std::path::PathBuf;
use tomograf_sim::Volume;
use tomograf_sim::attenuation::{Attenuation, mu_water_per_mm};

/// A scalar field on a regular grid in the DICOM LPS world frame (mm).
///
/// The array is in numpy order ``[k, j, i]`` (z, y, x for an axial CT; ``i``, the
/// first NIfTI/DICOM index axis, is the fastest). ``spacing`` is (sx, sy, sz) in mm
/// along (i, j, k); ``origin`` is the world position (LPS, mm) of the **centre** of
/// voxel (0, 0, 0); column ``a`` of ``direction`` is the world direction of index axis
/// ``a``. Voxel (i, j, k) is centred at ``origin + direction @ (spacing * (i, j, k))``.
/// Values are HU for CT volumes, or linear attenuation in mm⁻¹ after
/// :meth:`Volume.to_mu`; the projectors integrate mm⁻¹.
#[pyclass(module = "tomograf", name = "Volume", frozen)]
pub struct PyVolume {
    pub(crate) inner: Volume,
}

pub(crate) fn vec3(name: &str, v: [f64; 3]) -> PyResult<DVec3> {
    let d = DVec3::from(v);
    if d.is_finite() {
        Ok(d)
    } else {
        Err(errors::value(format!("{name} {d} is not finite")))
    }
}

impl PyVolume {
    /// Wraps a volume.
    pub fn wrap(inner: Volume) -> Self {
        Self { inner }
    }
}

#[pymethods]
impl PyVolume {
    /// A volume from a 3-D array ``[k, j, i]`` (converted to float32; NaN/Inf refused).
    ///
    /// ``spacing``: voxel size (sx, sy, sz) in mm along (i, j, k). ``origin``: world LPS
    /// position (mm) of the centre of voxel (0, 0, 0); default: the grid is centred on
    /// the world origin. ``direction``: 3×3, columns = world directions of (i, j, k),
    /// orthonormal (default identity).
    #[new]
    #[pyo3(signature = (array, spacing, origin=None, direction=None))]
    fn new(
        py: Python<'_>,
        array: PyArrayLike3<'_, f32, AllowTypeChange>,
        spacing: [f64; 3],
        origin: Option<[f64; 3]>,
        direction: Option<[[f64; 3]; 3]>,
    ) -> PyResult<Self> {
        let view = array.as_array();
        let (nk, nj, ni) = view.dim();
        let data: Vec<f32> = view.iter().copied().collect(); // C order: i fastest
        let dims = [ni, nj, nk];
        let spacing = DVec3::from(spacing);
        let direction = match direction {
            // Rows given in Python; glam takes columns.
            Some(m) => DMat3::from_cols_array_2d(&m).transpose(),
            None => DMat3::IDENTITY,
        };
        let inner = py.detach(move || match origin {
            Some(o) => Volume::new(dims, spacing, DVec3::from(o), direction, data),
            None => {
                let half = (DVec3::new(ni as f64, nj as f64, nk as f64) - 1.0) * 0.5;
                let o = -(direction * (half * spacing));
                Volume::new(dims, spacing, o, direction, data)
            }
        });
        Ok(Self::wrap(inner.map_err(errors::sim)?))
    }

    /// Reads a CT volume: a NIfTI file (``.nii``/``.nii.gz``, RAS converted to LPS) or a
    /// folder holding one DICOM CT series. Values as stored (HU for CT).
    /// Raises ``FileNotFoundError``/``OSError`` when the file cannot be read and
    /// ``ValueError`` when its content is not a usable volume.
    #[staticmethod]
    #[pyo3(signature = (path, allow_non_ct=false))]
    fn load(py: Python<'_>, path: PathBuf, allow_non_ct: bool) -> PyResult<Self> {
        let v = py.detach(|| {
            if path.is_dir() {
                tomograf_datasets::dicom::read_dicom_series(&path, allow_non_ct)
            } else {
                tomograf_datasets::nifti::read_nifti(&path)
            }
        });
        Ok(Self::wrap(v.map_err(errors::dataset)?))
    }

    /// Writes the volume as NIfTI-1 (``.nii`` or ``.nii.gz``; LPS converted to RAS in the
    /// affine), atomically.
    fn save_nifti(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| tomograf_datasets::nifti::write_nifti(&path, &self.inner))
            .map_err(errors::dataset)
    }

    /// A copy of the voxels as a float32 array of shape ``(nk, nj, ni)`` (numpy order
    /// ``[k, j, i]``).
    #[getter]
    fn array<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let [ni, nj, nk] = self.inner.dims();
        let a = ndarray::Array3::from_shape_vec((nk, nj, ni), self.inner.data().to_vec())
            .map_err(|e| errors::value(e.to_string()))?;
        Ok(a.into_pyarray(py))
    }

    /// Voxels along (i, j, k) — the reverse of ``array.shape``.
    #[getter]
    fn dims(&self) -> (usize, usize, usize) {
        let [a, b, c] = self.inner.dims();
        (a, b, c)
    }

    /// Numpy shape of :attr:`array`: ``(nk, nj, ni)``.
    #[getter]
    fn shape(&self) -> (usize, usize, usize) {
        let [a, b, c] = self.inner.dims();
        (c, b, a)
    }

    /// Voxel size (sx, sy, sz) in mm along (i, j, k).
    #[getter]
    fn spacing(&self) -> (f64, f64, f64) {
        self.inner.spacing().into()
    }

    /// World LPS position (mm) of the centre of voxel (0, 0, 0).
    #[getter]
    fn origin(&self) -> (f64, f64, f64) {
        self.inner.origin().into()
    }

    /// 3×3 float64 array; column ``a`` is the world (LPS) direction of index axis ``a``.
    #[getter]
    fn direction<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let m = self.inner.direction();
        let rows = ndarray::Array2::from_shape_fn((3, 3), |(r, c)| m.col(c)[r]);
        rows.into_pyarray(py)
    }

    /// World LPS position (mm) of the centre of the grid.
    #[getter]
    fn centre(&self) -> (f64, f64, f64) {
        self.inner.centre().into()
    }

    /// World LPS position (mm) of continuous index (i, j, k) (voxel centres at integers).
    fn index_to_world(&self, ijk: [f64; 3]) -> (f64, f64, f64) {
        self.inner.index_to_world(DVec3::from(ijk)).into()
    }

    /// Continuous index (i, j, k) of a world LPS point (mm).
    fn world_to_index(&self, p: [f64; 3]) -> (f64, f64, f64) {
        self.inner.world_to_index(DVec3::from(p)).into()
    }

    /// (min, max) of the voxel values.
    fn min_max(&self) -> (f32, f32) {
        self.inner.min_max()
    }

    /// HU → linear attenuation (mm⁻¹): ``mu = mu_water · max(0, 1 + HU/1000)``.
    ///
    /// Give either the effective photon energy ``energy_kev`` (water from the shipped
    /// xraydb/Elam table; default 60 keV) or ``mu_water_per_mm`` directly. Returns a new
    /// volume on the same grid.
    #[pyo3(signature = (energy_kev=None, mu_water_per_mm=None))]
    fn to_mu(
        &self,
        py: Python<'_>,
        energy_kev: Option<f64>,
        mu_water_per_mm: Option<f64>,
    ) -> PyResult<Self> {
        let att = match (energy_kev, mu_water_per_mm) {
            (Some(_), Some(_)) => {
                return Err(errors::value(
                    "give energy_kev or mu_water_per_mm, not both",
                ));
            }
            (_, Some(m)) => Attenuation::Hounsfield { mu_water_per_mm: m },
            (e, None) => Attenuation::hounsfield_at_kev(e.unwrap_or(60.0)).map_err(errors::sim)?,
        };
        let copy = self.inner.clone();
        let mu = py.detach(|| att.to_mu(copy)).map_err(errors::sim)?;
        Ok(Self::wrap(mu))
    }

    fn __repr__(&self) -> String {
        let [ni, nj, nk] = self.inner.dims();
        let s = self.inner.spacing();
        let o = self.inner.origin();
        format!(
            "Volume(dims=({ni}, {nj}, {nk}), spacing=({}, {}, {}) mm, origin=({}, {}, {}) mm)",
            s.x, s.y, s.z, o.x, o.y, o.z
        )
    }
}

/// Linear attenuation of water (mm⁻¹) at a photon energy in keV (xraydb / Elam 2002,
/// log–log interpolated). Raises ``ValueError`` outside the table.
#[pyfunction]
pub fn mu_water(energy_kev: f64) -> PyResult<f64> {
    mu_water_per_mm(energy_kev).map_err(errors::sim)
}

/// (lowest, highest) photon energy in keV that :func:`mu_water` covers.
#[pyfunction]
pub fn water_energy_range_kev() -> (f64, f64) {
    tomograf_sim::attenuation::water_energy_range_kev()
}
