//! Pixels whose recorded signal was clipped, summed over the views of a run: photon
//! starvation (at most half a signal unit above the dark, so −log underreads the line
//! integral) and saturation (the detector's ceiling or the ADC's top code), and the warning
//! both the command line and Python give the user.

/// Clipped and saturated pixels over a run's views.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Clipping {
    /// Photon-starved pixels.
    pub clipped: usize,
    /// Saturated pixels.
    pub saturated: usize,
    /// Pixels recorded.
    pub pixels: usize,
    /// Views with a starved pixel.
    pub views_clipped: usize,
    /// Views with a saturated pixel.
    pub views_saturated: usize,
}

impl Clipping {
    /// Adds one view with `clipped` starved and `saturated` saturated of `pixels` pixels.
    pub fn add(&mut self, clipped: usize, saturated: usize, pixels: usize) {
        self.clipped += clipped;
        self.saturated += saturated;
        self.pixels += pixels;
        self.views_clipped += usize::from(clipped > 0);
        self.views_saturated += usize::from(saturated > 0);
    }

    /// What to tell the user (`None` when nothing was clipped): `mas` is the exposure per
    /// view, `setting` how the caller sets it (e.g. "[spectrum] mas or --mas", "mas="),
    /// `signal_unit` whether the detector counts in units
    /// ([`crate::detector::DetectorModel::has_signal_unit`]): with none, a starved pixel is one
    /// whose expected signal underflowed to nothing, which no exposure restores.
    pub fn warning(&self, mas: f64, setting: &str, signal_unit: bool) -> Option<String> {
        let mut lines = Vec::new();
        if self.clipped > 0 && signal_unit {
            lines.push(format!(
                "warning: {} of {} pixels ({} view(s)) recorded at most half a signal unit \
                 (ADU or count) above the dark: photon starvation. Their −log reads \
                 ln(2·(flat − dark)), less than the object's line integral. Raise the exposure \
                 (mas = {mas} now: {setting}).",
                self.clipped, self.pixels, self.views_clipped
            ));
        } else if self.clipped > 0 {
            lines.push(format!(
                "warning: {} of {} pixels ({} view(s)) recorded no signal above the dark: the \
                 beam's transmission through the object rounds to zero in the recorded image \
                 (float32). Their −log reads ln((flat − dark) / 2.2e-308), about 708 + \
                 ln(flat − dark), less than the object's line integral; a higher-energy \
                 spectrum or a less attenuating object records them.",
                self.clipped, self.pixels, self.views_clipped
            ));
        }
        if self.saturated > 0 {
            lines.push(format!(
                "warning: {} of {} pixels ({} view(s)) are at the detector's ceiling \
                 (saturation or the ADC's top code): their signal is clipped. Lower the \
                 exposure (mas = {mas} now: {setting}) or raise the readout's range.",
                self.saturated, self.pixels, self.views_saturated
            ));
        }
        (!lines.is_empty()).then(|| lines.join("\n"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn warns_only_when_something_was_clipped() {
        let mut c = Clipping::default();
        c.add(0, 0, 100);
        assert_eq!(c.warning(1.0, "--mas", true), None);
        c.add(3, 0, 100);
        c.add(0, 2, 100);
        let w = c.warning(0.5, "mas=", true).unwrap();
        assert!(
            w.contains("3 of 300 pixels (1 view(s))") && w.contains("starvation"),
            "{w}"
        );
        assert!(
            w.contains("2 of 300 pixels") && w.contains("ceiling"),
            "{w}"
        );
        assert!(w.contains("mas = 0.5 now: mas="), "{w}");
        // Without a signal unit no exposure helps, and the −log is not ln(2·(flat − dark)).
        let w = c.warning(0.5, "mas=", false).unwrap();
        assert!(
            w.contains("3 of 300 pixels (1 view(s)) recorded no signal above the dark")
                && w.contains("708 + ln(flat − dark)")
                && !w.contains("ln(2·(flat − dark))"),
            "{w}"
        );
    }
}
