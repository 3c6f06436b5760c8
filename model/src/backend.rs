//! Which burn backend runs the model, chosen at run time through the device.
//!
//! Default: burn's `flex` CPU backend (multi-threaded, SIMD). `--features ndarray` keeps the
//! older CPU backend selectable; `cuda` and `wgpu` add GPU backends.

use crate::error::{ModelError, Result};
use burn::tensor::Device;

/// Names of the backends compiled into this build.
pub fn available() -> Vec<&'static str> {
    let mut v = Vec::new();
    if cfg!(feature = "flex") {
        v.push("flex");
    }
    if cfg!(feature = "ndarray") {
        v.push("ndarray");
    }
    if cfg!(feature = "cuda") {
        v.push("cuda");
    }
    if cfg!(feature = "wgpu") {
        v.push("wgpu");
    }
    v
}

/// The device for backend `name` (`flex`, `ndarray`, `cuda`, `wgpu`), with autodiff.
pub fn device(name: &str) -> Result<Device> {
    let dev = match name {
        #[cfg(feature = "flex")]
        "flex" => Device::flex(),
        #[cfg(feature = "ndarray")]
        #[allow(deprecated)]
        "ndarray" => Device::ndarray(),
        #[cfg(feature = "cuda")]
        "cuda" => Device::cuda(0),
        #[cfg(feature = "wgpu")]
        "wgpu" => Device::wgpu(burn::tensor::DeviceKind::DefaultDevice),
        other => {
            return Err(ModelError::Invalid(format!(
                "backend '{other}' is not compiled in; available: {}",
                available().join(", ")
            )));
        }
    };
    Ok(dev.autodiff())
}

/// The first compiled backend (GPU first when compiled in).
pub fn default_name() -> &'static str {
    for n in ["cuda", "wgpu", "flex", "ndarray"] {
        if available().contains(&n) {
            return n;
        }
    }
    "flex"
}
