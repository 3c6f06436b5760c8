//! The scene resolved against the volume: geometry, views, projector, quantity.

use crate::scene::{ExplicitView, Scene};
use anyhow::{Result, bail};
use glam::DVec3;
use tomograf_sim::accel::SkipOptions;
use tomograf_sim::geometry::angles;
use tomograf_sim::{
    Beam, Detector, Geometry, Pose, Projector, Quantity, Tracer, View, ViewBeam, Volume,
};

/// Everything needed to render, resolved from a scene.
pub struct Job {
    pub geometry: Option<Geometry>,
    pub poses: Vec<Pose>,
    pub views: Vec<View>,
    pub projector: Projector,
    /// The exact Siddon tracer (`[projector] tracer`).
    pub tracer: Tracer,
    /// Empty-space skipping (`--empty-below`).
    pub skipping: Option<SkipOptions>,
    pub quantity: Quantity,
}

/// Resolves geometry, views, projector and quantity against the (mu) volume.
pub fn resolve(scene: &Scene, mu: &Volume) -> Result<Job> {
    let g = &scene.geometry;
    let beam = match g.beam.as_deref().unwrap_or("cone") {
        "cone" => Beam::Cone {
            sad_mm: g.sad_mm.unwrap_or(1000.0),
            sid_mm: g.sid_mm.unwrap_or(1500.0),
        },
        "parallel" => {
            if g.sad_mm.is_some() || g.sid_mm.is_some() {
                bail!("SAD and SID do not apply to a parallel beam");
            }
            Beam::Parallel
        }
        other => bail!("unknown beam '{other}': use cone or parallel"),
    };
    let mut poses = Vec::new();
    for p in scene.views.poses.iter().flatten() {
        poses.push(angles::parse_pose(p)?);
    }
    if let Some(a) = &scene.views.arc {
        poses.extend(angles::parse_arc(a)?);
    }
    let explicit: Vec<View> = scene
        .views
        .explicit
        .iter()
        .map(explicit_view)
        .collect::<Result<_>>()?;
    if poses.is_empty() && explicit.is_empty() {
        poses.push(Pose::AP);
    }
    let d = &scene.detector;
    let offset = d.offset_mm.unwrap_or([0.0, 0.0]);
    let mut geometry = Geometry {
        beam,
        detector: Detector {
            rows: d.rows.unwrap_or(256),
            cols: d.cols.unwrap_or(256),
            pitch_u_mm: 1.0,
            pitch_v_mm: 1.0,
            offset_u_mm: offset[0],
            offset_v_mm: offset[1],
        },
        isocentre: g
            .isocentre_mm
            .map(DVec3::from)
            .unwrap_or_else(|| mu.centre()),
    };
    // Explicit views carry their own pixel vectors: the pitch only matters for pose views.
    let pitch = match d.pitch_mm {
        Some(p) => p,
        None if poses.is_empty() => [1.0, 1.0],
        None => {
            let p = geometry.fit_pitch(&poses, mu)?;
            [p, p]
        }
    };
    geometry.detector.pitch_u_mm = pitch[0];
    geometry.detector.pitch_v_mm = pitch[1];
    let mut views = geometry.views(&poses)?;
    views.extend(explicit);

    let p = &scene.projector;
    let projector = Projector::from_name(
        p.kind.as_deref().unwrap_or("siddon"),
        p.step_voxels.unwrap_or(0.5),
    )?;
    if projector == Projector::Siddon && p.step_voxels.is_some() {
        bail!("[projector] step_voxels (--step) applies to the trilinear projector only");
    }
    let tracer = match p.tracer.as_deref() {
        None => Tracer::Auto,
        Some(name) => Tracer::from_name(name)
            .map_err(|e| anyhow::anyhow!("[projector] tracer (--tracer): {e}"))?,
    };
    if projector != Projector::Siddon && tracer != Tracer::Auto {
        bail!(
            "[projector] tracer (--tracer) chooses among the exact Siddon tracers; the \
             trilinear projector has one marcher"
        );
    }
    let skipping = p.empty_below_per_mm.map(|threshold| SkipOptions {
        threshold,
        ..SkipOptions::default()
    });
    let o = &scene.output;
    let quantity = Quantity::from_name(
        o.quantity.as_deref().unwrap_or("line-integral"),
        o.i0.unwrap_or(1.0),
    )?;
    if o.i0.is_some() && !matches!(quantity, Quantity::Intensity { .. }) {
        bail!("[output] i0 (--i0) applies to quantity = \"intensity\" (--quantity intensity) only");
    }
    quantity.validate()?;
    Ok(Job {
        geometry: (!poses.is_empty()).then_some(geometry),
        poses,
        views,
        projector,
        tracer,
        skipping,
        quantity,
    })
}

fn explicit_view(e: &ExplicitView) -> Result<View> {
    let beam = match (e.source_mm, e.direction) {
        (Some(s), None) => ViewBeam::Cone {
            source: DVec3::from(s),
        },
        (None, Some(d)) => {
            let d = DVec3::from(d);
            if !d.is_finite() || d.length() == 0.0 {
                bail!("explicit view direction {d} is zero");
            }
            ViewBeam::Parallel {
                direction: d.normalize(),
            }
        }
        _ => {
            bail!("an explicit view needs exactly one of source_mm (cone) or direction (parallel)")
        }
    };
    let v = View {
        beam,
        detector_origin: DVec3::from(e.detector_origin_mm),
        u: DVec3::from(e.u_mm),
        v: DVec3::from(e.v_mm),
        rows: e.rows,
        cols: e.cols,
    };
    v.validate()?;
    Ok(v)
}
