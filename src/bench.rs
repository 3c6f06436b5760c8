//! `tomograf bench`: parses the flags, runs the [`tomograf_bench`] sections they name,
//! prints the markdown and writes it where `--out` says.

use anyhow::Result;
use clap::Args;
use std::path::{Path, PathBuf};
use tomograf_bench::{Options, accel, backend, cpu_model, model, physics, projector, scatter};

#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Small sizes only (a smoke test that runs in seconds).
    #[arg(long)]
    pub quick: bool,
    /// Renders per measurement (the median is reported).
    #[arg(long, default_value_t = 9)]
    pub repeats: usize,
    /// Also write the markdown here (e.g. docs/benchmarks.md).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Measure the polychromatic physics and detector instead (e.g. with
    /// `--out docs/physics-benchmarks.md`).
    #[arg(long)]
    pub physics: bool,
    /// Measure TomoGRAF's training and inference iterations instead (e.g. with
    /// `--out docs/model-benchmarks.md`).
    #[arg(long)]
    pub model: bool,
    /// With --model: measure on this backend (as compiled in, e.g. `cuda` with
    /// `--features tomograf-model/cuda`) against `flex` in the same run: agreement of
    /// losses and reconstructions, and speed-ups.
    #[arg(long, requires = "model")]
    pub backend: Option<String>,
    /// Only the empty-space skipping and mesh sections (docs/benchmarks.md, docs/meshes.md).
    #[arg(long)]
    pub accel_only: bool,
    /// With --accel-only: only this section (skipping or meshes).
    #[arg(long, requires = "accel_only")]
    pub section: Option<String>,
    /// Measure the scatter engine's speed against its error on this CT instead (NIfTI or
    /// DICOM folder; e.g. with `--out docs/scatter-speed.md`).
    #[arg(long, value_name = "CT")]
    pub scatter: Option<PathBuf>,
    /// With --scatter: histories of the full-resolution reference.
    #[arg(long, requires = "scatter", default_value_t = 400_000)]
    pub reference_photons: u64,
    /// With --scatter: keep the reference image here (NPY, and a .txt key beside it) and
    /// reuse it when the CT, photons and view are the same.
    #[arg(long, requires = "scatter")]
    pub reference_cache: Option<PathBuf>,
    /// With --scatter: the view of the 72 that is scored (0, the default: AP; 18: lateral).
    #[arg(long, requires = "scatter", default_value_t = 0)]
    pub view: usize,
    /// With --scatter: the 72-view orbits only (the one-view ladder skipped).
    #[arg(long, requires = "scatter", conflicts_with = "ladder_only")]
    pub orbit_only: bool,
    /// With --scatter: the one-view ladder only (the orbits skipped).
    #[arg(long, requires = "scatter")]
    pub ladder_only: bool,
    /// With --scatter: runs of each setting, taken in turn (the median is reported).
    #[arg(long, requires = "scatter", default_value_t = 2)]
    pub rounds: usize,
}

pub fn run(args: BenchArgs) -> Result<()> {
    let o = Options {
        quick: args.quick,
        repeats: args.repeats,
    };
    let out = args.out.as_deref();
    if let Some(ct) = &args.scatter {
        let so = scatter::ScatterOptions {
            quick: o.quick,
            rounds: args.rounds,
            orbit_only: args.orbit_only,
            ladder_only: args.ladder_only,
            view: args.view,
            reference_photons: args.reference_photons,
            reference_cache: args.reference_cache.clone(),
        };
        let md = format!(
            "Measured by `tomograf bench --scatter {}{}{}{}`.\n\n{}",
            ct.display(),
            if o.quick { " --quick" } else { "" },
            if args.view > 0 {
                format!(" --view {}", args.view)
            } else {
                String::new()
            },
            if args.orbit_only {
                " --orbit-only"
            } else if args.ladder_only {
                " --ladder-only"
            } else {
                ""
            },
            scatter::section(ct, &so)?
        );
        return write_page("Scatter at data-set speed", &md, out);
    }
    if args.physics {
        return write_page(
            "Physics benchmarks",
            &physics::section(o.quick, o.repeats)?,
            out,
        );
    }
    let measured = |flags: &str| {
        format!(
            "Measured by `tomograf bench {flags}{}` on {}, {} threads.\n\n",
            if o.quick { " --quick" } else { "" },
            cpu_model(),
            rayon::current_num_threads()
        )
    };
    if let Some(name) = &args.backend {
        let md = measured(&format!("--model --backend {name}"))
            + &backend::section(o.quick, o.repeats, name)?;
        return write_page("Model benchmarks: GPU backend", &md, out);
    }
    if args.model {
        let md = measured("--model") + &model::section(o.quick, o.repeats)?;
        return write_page("Model benchmarks", &md, out);
    }
    if args.accel_only {
        // As before the sections moved: the page's header, then the sections, no title.
        let md = accel::page(&o, args.section.as_deref(), projector::header(&o)?)?;
        println!("{md}");
        if let Some(path) = out {
            write(path, &md)?;
        }
        return Ok(());
    }
    write_page("Projector benchmarks", &projector::page(&o)?, out)
}

/// Prints the markdown and, when asked, writes it (atomically) under a title.
fn write_page(title: &str, md: &str, out: Option<&Path>) -> Result<()> {
    println!("{md}");
    if let Some(path) = out {
        write(path, &format!("# {title}\n\n{md}"))?;
    }
    Ok(())
}

fn write(path: &Path, text: &str) -> Result<()> {
    tomograf_datasets::atomic::write_atomic(path, |w| {
        std::io::Write::write_all(w, text.as_bytes())
    })?;
    eprintln!("wrote {}", path.display());
    Ok(())
}
