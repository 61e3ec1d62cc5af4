//! Mean, amplitude and frequency of a periodic quantity, as the Turek-Hron benchmarks report
//! them (Turek & Hron 2006, section 3): over the last period of the signal,
//! `mean = (max + min) / 2`, `amplitude = (max - min) / 2`, `frequency = 1 / period`.
//!
//! The period is the time between the last two upward crossings of the signal's mid-value (over
//! the analysed window), each located by linear interpolation between the samples; the extrema
//! are the samples' (the sampling error of an extremum is about `(pi dt / T)^2 / 2` of the
//! amplitude: 1.5e-4 at 100 samples a period). A crossing counts only after the signal has been
//! below the mid-value by half the half range since the last one, so that noise about the
//! mid-value does not make crossings (an FSI run's forces jitter from step to step by up to a
//! fifth of their half range as the adapted mesh changes: Turek-Hron FSI3's drag with dt =
//! 0.0005), and a signal whose range is below 1e-9 of its size does not oscillate. Such jitter
//! enters the extrema, hence the amplitude, by its own size. The mid-value and range are the whole
//! window's: the window (`from` on) should hold a settled oscillation, since one whose amplitude
//! falls below about half its largest in the window no longer arms the crossings.

/// The statistics of the last period of a signal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Oscillation {
    pub mean: f64,
    pub amplitude: f64,
    pub frequency: f64,
    /// Whole periods in the analysed window.
    pub periods: usize,
}

/// The last period of `y(t)` over the samples with `t >= from`; `None` when the window holds
/// fewer than two upward crossings of its mid-value (less than one whole period) or a
/// non-finite value.
pub fn last_period(t: &[f64], y: &[f64], from: f64) -> Option<Oscillation> {
    let window: Vec<(f64, f64)> = t.iter().zip(y).filter(|(t, _)| **t >= from).map(|(t, y)| (*t, *y)).collect();
    if window.iter().any(|(t, y)| !t.is_finite() || !y.is_finite()) {
        return None;
    }
    let (lo, hi) = window.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (_, y)| (lo.min(*y), hi.max(*y)));
    if !(hi - lo > 1e-9 * hi.abs().max(lo.abs())) {
        return None;
    }
    let (mid, armed_below) = (0.5 * (lo + hi), 0.5 * (lo + hi) - 0.25 * (hi - lo));
    let mut crossings = Vec::new();
    let mut armed = false;
    for w in window.windows(2) {
        armed |= w[0].1 < armed_below;
        if armed && w[0].1 < mid && w[1].1 >= mid {
            crossings.push(w[0].0 + (mid - w[0].1) / (w[1].1 - w[0].1) * (w[1].0 - w[0].0));
            armed = false;
        }
    }
    let [.., a, b] = crossings[..] else { return None };
    let (lo, hi) =
        window.iter().filter(|(t, _)| *t >= a && *t <= b).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (_, y)| (lo.min(*y), hi.max(*y)));
    Some(Oscillation { mean: 0.5 * (hi + lo), amplitude: 0.5 * (hi - lo), frequency: 1.0 / (b - a), periods: crossings.len() - 1 })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sampled `m + a sin(2 pi f t) + decaying transient` gives back `m`, `a`, `f` (4.4 periods
    /// in the window: at least 3 whole ones between its first and last upward crossings).
    #[test]
    fn a_sampled_sine_gives_its_mean_amplitude_and_frequency() {
        let (m, a, f, dt) = (-63.6, 65.2, 1.1, 1e-3);
        let t: Vec<f64> = (0..8000).map(|k| k as f64 * dt).collect();
        let y: Vec<f64> = t.iter().map(|t| m + a * (2.0 * std::f64::consts::PI * f * t).sin() + 30.0 * (-3.0 * t).exp()).collect();
        let o = last_period(&t, &y, 4.0).unwrap();
        assert!((o.mean - m).abs() < 1e-3 * a && (o.amplitude - a).abs() < 1e-3 * a, "{o:?}");
        assert!((o.frequency - f).abs() < 1e-5 * f, "{o:?}");
        assert!(o.periods >= 3, "{o:?}");
        // Less than a period: nothing to report.
        assert_eq!(last_period(&t, &y, 7.5), None);
        assert_eq!(last_period(&t[..10], &y[..10], 0.0), None);
        // Noise about the mid-value of a sine makes no extra crossings.
        let noisy: Vec<f64> = y.iter().enumerate().map(|(k, v)| v + if k % 2 == 0 { 1e-3 } else { -1e-3 }).collect();
        let n = last_period(&t, &noisy, 4.0).unwrap();
        assert!((n.frequency - f).abs() < 1e-4 * f, "{n:?}");
        // Step-to-step jitter of a fifth of the half range (the mid-value crossed several times
        // around each true crossing) makes no extra crossings either.
        let jittery: Vec<f64> = y.iter().enumerate().map(|(k, v)| v + 0.2 * a * [1.0, -0.6, 0.3, -1.0, 0.5][k % 5]).collect();
        let j = last_period(&t, &jittery, 4.0).unwrap();
        assert!((j.frequency - f).abs() < 2e-3 * f && (j.mean - m).abs() < 0.05 * a, "{j:?}");
        // A constant (to round-off) does not oscillate.
        let flat: Vec<f64> = t.iter().map(|t| 5.0 + 1e-14 * (40.0 * t).sin()).collect();
        assert_eq!(last_period(&t, &flat, 0.0), None);
    }
}
