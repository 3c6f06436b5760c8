//! Named views and angle sets.

use super::Pose;
use crate::error::{Result, SimError};

/// Most views one arc may hold (a million: the poses and views of a job are held in
/// memory, ~1 KiB each).
pub const MAX_VIEWS: usize = 1_000_000;

/// `count` poses starting at θ = `start_deg`, every `step_deg`, at elevation `phi_deg`
/// (e.g. `arc(0.0, 5.0, 72, 0.0)` is the paper's 72 views every 5° of a full rotation).
pub fn arc(start_deg: f64, step_deg: f64, count: usize, phi_deg: f64) -> Result<Vec<Pose>> {
    if count == 0 {
        return Err(SimError::InvalidGeometry(
            "an arc needs at least one view".into(),
        ));
    }
    if count > MAX_VIEWS {
        return Err(SimError::InvalidGeometry(format!(
            "an arc of {count} views is more than {MAX_VIEWS} in one job; split it into \
             several jobs (e.g. `dataset --shard`, or arcs with other start angles)"
        )));
    }
    if !(start_deg.is_finite() && step_deg.is_finite() && phi_deg.is_finite()) {
        return Err(SimError::InvalidGeometry(
            "arc angles must be finite".into(),
        ));
    }
    Ok((0..count)
        .map(|i| Pose::new(start_deg + i as f64 * step_deg, phi_deg))
        .collect())
}

/// Parses a named view (`ap`, `pa`, `lateral`/`lat`/`left-lateral`, `right-lateral`) or
/// an explicit `θ` / `θ,φ` in degrees.
pub fn parse_pose(text: &str) -> Result<Pose> {
    let t = text.trim().to_ascii_lowercase();
    let named = match t.as_str() {
        "ap" => Some(Pose::AP),
        "pa" => Some(Pose::new(180.0, 0.0)),
        "lateral" | "lat" | "left-lateral" | "ll" => Some(Pose::LATERAL),
        "right-lateral" | "rl" => Some(Pose::new(-90.0, 0.0)),
        _ => None,
    };
    if let Some(p) = named {
        return Ok(p);
    }
    let parts: Vec<&str> = t.split(',').map(str::trim).collect();
    let num = |s: &str| {
        s.parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| {
            SimError::InvalidGeometry(format!(
                "view '{text}' is neither a named view (ap, pa, lateral, right-lateral) nor 'θ' or 'θ,φ' in degrees"
            ))
        })
    };
    match parts.as_slice() {
        [th] => Ok(Pose::new(num(th)?, 0.0)),
        [th, ph] => Ok(Pose::new(num(th)?, num(ph)?)),
        _ => Err(SimError::InvalidGeometry(format!(
            "view '{text}' is neither a named view nor 'θ' or 'θ,φ'"
        ))),
    }
}

/// Parses an arc `START:STEP:COUNT` (degrees, degrees, views), e.g. `0:5:72`.
pub fn parse_arc(text: &str) -> Result<Vec<Pose>> {
    let bad = || {
        SimError::InvalidGeometry(format!(
            "arc '{text}' must be START:STEP:COUNT, e.g. 0:5:72 for 72 views every 5°"
        ))
    };
    let parts: Vec<&str> = text.split(':').map(str::trim).collect();
    let [a, b, c] = parts.as_slice() else {
        return Err(bad());
    };
    let start = a.parse::<f64>().map_err(|_| bad())?;
    let step = b.parse::<f64>().map_err(|_| bad())?;
    let count = c.parse::<usize>().map_err(|_| bad())?;
    arc(start, step, count, 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_named_and_numeric_views() {
        assert_eq!(parse_pose("AP").unwrap(), Pose::AP);
        assert_eq!(parse_pose("lateral").unwrap(), Pose::LATERAL);
        assert_eq!(parse_pose("30,10").unwrap(), Pose::new(30.0, 10.0));
        assert!(parse_pose("sideways").is_err());
        let a = parse_arc("0:5:72").unwrap();
        assert_eq!(a.len(), 72);
        assert_eq!(a[71].theta_deg, 355.0);
        assert!(parse_arc("0:5").is_err());
        assert!(parse_arc("0:5:0").is_err());
    }
}
