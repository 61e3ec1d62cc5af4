//! Per-cycle statistics of a periodically driven run (a heart valve over cardiac cycles): the
//! volumes through the valve, when it closes and opens, and the peaks of chosen quantities, for
//! every whole cycle `k` (1-based) of `[t_0 + (k - 1) T, t_0 + k T]` in the run's history.
//!
//! With `Q(t)` the flux through the valve (forward positive) and `F(t)` the force of the
//! valve's contact (closed while `F > 0`), over cycle `k`:
//! - forward volume `int max(Q, 0) dt`, backward volume `int max(-Q, 0) dt` (trapezoidal rule on
//!   the samples' positive and negative parts);
//! - leak volume: the backward volume over the steps that start and end closed;
//! - closing time: the first sample, from the cycle's start, at which the valve is closed after
//!   a sample at which it was open; opening time: the first at which it is open after one at
//!   which it was closed (`NaN` when the valve does not close or open in the cycle);
//! - the largest value of each peak quantity, and of each forward-peak quantity over the
//!   forward flow (the steps of the forward mean, below): a valve's peak systolic jet, without
//!   the leaflets' sweep as they close;
//! - the mean of each forward-mean quantity over the forward flow, `int g [Q > 0] dt / int [Q >
//!   0] dt` over the steps that start and end with `Q > 0` and the valve open (trapezoidal rule;
//!   a forward flux while closed, a leaflet ringing after it shut, is not systole): the mean
//!   systolic transvalvular gradient of a valve, the clinical measure of its stenosis.

/// The statistics of one whole cycle.
#[derive(Clone, Debug, PartialEq)]
pub struct Cycle {
    /// 1-based.
    pub index: usize,
    pub forward_volume: f64,
    pub backward_volume: f64,
    /// `NaN` without a contact force.
    pub leak_volume: f64,
    /// Time from the cycle's start; `NaN` when it does not close (or no contact force).
    pub closing_time: f64,
    /// Time from the cycle's start; `NaN` when it does not open (or no contact force).
    pub opening_time: f64,
    /// The largest value of each peak quantity, in their order.
    pub peaks: Vec<f64>,
    /// The largest value of each forward-peak quantity over the cycle's forward flow while
    /// open, in their order (`NaN` when no step has forward flow throughout; `NaN` samples are
    /// passed over, as for the peaks).
    pub forward_peaks: Vec<f64>,
    /// The mean of each forward-mean quantity over the cycle's forward flow while open, in their
    /// order (`NaN` when no step has forward flow throughout).
    pub forward_means: Vec<f64>,
}

/// The quantities sampled with the flux whose statistics [`cycles`] reports, each a slice of
/// the same length as the samples.
#[derive(Clone, Copy, Debug, Default)]
pub struct CycleQuantities<'a> {
    /// Reported by their largest value in each cycle.
    pub peaks: &'a [&'a [f64]],
    /// Reported by their largest value over each cycle's forward flow.
    pub forward_peaks: &'a [&'a [f64]],
    /// Reported by their mean over each cycle's forward flow.
    pub forward_means: &'a [&'a [f64]],
}

/// The whole cycles of period `period` (cycle `k` spans `[t_0 + (k - 1) T, t_0 + k T]`, `t_0` the
/// `offset`: e.g. mid-diastole, so that each cycle holds one opening and one closing of a valve
/// whatever their small shifts from beat to beat) in the samples `t`
/// (increasing) of the flux `q`, the contact force `force` (if any) and the `quantities`: the
/// peak, forward-peak and forward-mean ones. A cycle is whole when the samples cover it to a step at its start (a run's history
/// starts at its first step's end) and to half a step at its end; a history that starts later
/// (a run started from another's state) has no whole cycles before that. A non-finite flux makes
/// the cycle's volumes `NaN`.
pub fn cycles(t: &[f64], q: &[f64], force: Option<&[f64]>, quantities: &CycleQuantities<'_>, period: f64, offset: f64) -> Vec<Cycle> {
    let CycleQuantities { peaks, forward_peaks, forward_means: means } = *quantities;
    let (Some(&first), Some(&last)) = (t.first(), t.last()) else { return Vec::new() };
    let step = if t.len() > 1 { (last - first) / (t.len() - 1) as f64 } else { 0.0 };
    let whole = ((last - offset + 0.5 * step) / period).floor().max(0.0) as usize;
    let covered = |k: usize| offset + (k - 1) as f64 * period >= first - 1.5 * step;
    (1..=whole)
        .filter(|&k| covered(k))
        .map(|k| {
            let (start, end) = (offset + (k - 1) as f64 * period, offset + k as f64 * period);
            // The samples of the cycle, with the one at its start (the end of the cycle before)
            // for the integrals and the changes of state.
            let tol = 1e-9 * period;
            let range = t.partition_point(|&s| s <= start + tol).saturating_sub(1)..t.partition_point(|&s| s <= end + tol);
            let inside = || range.clone().filter(|&i| t[i] > start + tol);
            let closed = |i: usize| force.is_some_and(|f| f[i] > 0.0);
            let (mut forward, mut backward, mut leak) = (0.0, 0.0, 0.0);
            for i in range.start + 1..range.end {
                let dt = t[i] - t[i - 1];
                forward += 0.5 * dt * (q[i - 1].max(0.0) + q[i].max(0.0));
                let back = 0.5 * dt * ((-q[i - 1]).max(0.0) + (-q[i]).max(0.0));
                backward += back;
                if closed(i - 1) && closed(i) {
                    leak += back;
                }
            }
            let change = |to_closed: bool| {
                (range.start + 1..range.end).find(|&i| closed(i - 1) != to_closed && closed(i) == to_closed).map_or(f64::NAN, |i| t[i] - start)
            };
            let open = |i: usize| q[i - 1] > 0.0 && q[i] > 0.0 && !closed(i - 1) && !closed(i);
            let forward_steps: Vec<usize> = (range.start + 1..range.end).filter(|&i| open(i)).collect();
            let duration: f64 = forward_steps.iter().map(|&i| t[i] - t[i - 1]).sum();
            let forward_mean = |g: &[f64]| forward_steps.iter().map(|&i| 0.5 * (t[i] - t[i - 1]) * (g[i - 1] + g[i])).sum::<f64>() / duration;
            let forward_peak = |g: &[f64]| forward_steps.iter().map(|&i| g[i - 1].max(g[i])).fold(f64::NAN, f64::max);
            let finite = q[range.clone()].iter().all(|v| v.is_finite());
            let volume = |v: f64| if finite { v } else { f64::NAN };
            Cycle {
                index: k,
                forward_volume: volume(forward),
                backward_volume: volume(backward),
                leak_volume: if force.is_some() { volume(leak) } else { f64::NAN },
                closing_time: change(true),
                opening_time: change(false),
                peaks: peaks.iter().map(|p| inside().map(|i| p[i]).fold(f64::NEG_INFINITY, f64::max)).collect(),
                forward_peaks: forward_peaks.iter().map(|g| forward_peak(g)).collect(),
                forward_means: means.iter().map(|g| if duration > 0.0 { forward_mean(g) } else { f64::NAN }).collect(),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two cycles of 1 (dt = 0.01) of a valve open on [0.1, 0.5) with `Q = sin(pi (t - 0.1) /
    /// 0.4)` forward (volume 0.8 / pi), then a backflow of 0.1 while closing on [0.5, 0.6), and
    /// closed from 0.6 with a leak of 0.01: the volumes to the trapezoidal rule's error, the
    /// times to the samples.
    #[test]
    fn the_volumes_times_and_peaks_of_each_whole_cycle() {
        let dt = 0.01;
        let t: Vec<f64> = (0..=250).map(|k| k as f64 * dt).collect();
        let phase = |t: f64| t - t.floor();
        let q: Vec<f64> = t
            .iter()
            .map(|&t| match phase(t) {
                s if (0.1..0.5).contains(&s) => (std::f64::consts::PI * (s - 0.1) / 0.4).sin(),
                s if (0.5..0.6).contains(&s) => -0.1,
                s if s >= 0.6 => -0.01,
                _ => -0.01,
            })
            .collect();
        let force: Vec<f64> = t.iter().map(|&t| if phase(t) >= 0.6 || phase(t) < 0.1 { 1.0 } else { 0.0 }).collect();
        let speed: Vec<f64> = t.iter().map(|&t| 2.0 + t).collect();
        let speeds: &[&[f64]] = &[&speed];
        let c = cycles(&t, &q, Some(&force), &CycleQuantities { peaks: speeds, forward_peaks: speeds, forward_means: speeds }, 1.0, 0.0);
        assert_eq!(c.len(), 2, "2.5 cycles: two whole ones");
        for (k, cycle) in c.iter().enumerate() {
            assert_eq!(cycle.index, k + 1);
            assert!((cycle.forward_volume - 0.8 / std::f64::consts::PI).abs() < 1e-3, "{cycle:?}");
            // Backward: 0.1 over 0.1, 0.01 over 0.5 (plus the half steps at the switches).
            assert!((cycle.backward_volume - (0.01 + 0.005)).abs() < 1.5e-3, "{cycle:?}");
            assert!((cycle.leak_volume - 0.005).abs() < 2e-4, "{cycle:?}");
            assert!((cycle.closing_time - 0.6).abs() < 1e-9 && (cycle.opening_time - 0.1).abs() < 1e-9, "{cycle:?}");
            // The peak of 2 + t over (k - 1, k]: the sample at the cycle's end.
            assert!((cycle.peaks[0] - (2.0 + (k + 1) as f64)).abs() < 1e-9, "{cycle:?}");
            // The mean of 2 + t over the forward flow: the steps with Q > 0 at both ends, from
            // k + 0.11 to k + 0.49 (or from k + 0.1, where round-off makes Q(k + 0.1) > 0): the
            // middle, k + 0.3, to half a step.
            assert!((cycle.forward_means[0] - (2.0 + k as f64 + 0.3)).abs() < 0.0051, "{cycle:?}");
            // Its largest value over the forward flow: at the last forward sample, k + 0.49.
            assert!((cycle.forward_peaks[0] - (2.0 + k as f64 + 0.49)).abs() < 1e-9, "{cycle:?}");
        }
        // A forward blip while closed (a leaflet ringing after it shut) is not systole: the
        // forward mean of a quantity that is 100 there is unchanged with the contact force.
        let mut blip = q.clone();
        let mut marked = speed.clone();
        for i in 70..73 {
            blip[i] = 0.05;
            marked[i] = 100.0;
        }
        let marks: &[&[f64]] = &[&marked];
        let with_blip =
            cycles(&t, &blip, Some(&force), &CycleQuantities { forward_peaks: marks, forward_means: marks, ..Default::default() }, 1.0, 0.0);
        assert!((with_blip[0].forward_means[0] - c[0].forward_means[0]).abs() < 1e-12, "{with_blip:?}");
        assert_eq!(with_blip[0].forward_peaks[0], c[0].forward_peaks[0], "{with_blip:?}");
        // Without a contact force: no leak, no times.
        let open = cycles(&t, &q, None, &CycleQuantities::default(), 1.0, 0.0);
        assert!(open[0].leak_volume.is_nan() && open[0].closing_time.is_nan() && open[0].opening_time.is_nan());
        assert!(cycles(&t[..50], &q[..50], None, &CycleQuantities::default(), 1.0, 0.0).is_empty());
        // A history from the first step's end (no t = 0 row) still has its first cycle; one
        // that starts at t = 0.6 has only the second.
        assert_eq!(cycles(&t[1..], &q[1..], None, &CycleQuantities::default(), 1.0, 0.0).len(), 2);
        let later = cycles(&t[60..], &q[60..], None, &CycleQuantities::default(), 1.0, 0.0);
        assert_eq!(later.iter().map(|c| c.index).collect::<Vec<_>>(), vec![2]);
        // A NaN in the flux: no volumes for its cycle.
        let mut broken = q.clone();
        broken[30] = f64::NAN;
        let b = cycles(&t, &broken, None, &CycleQuantities::default(), 1.0, 0.0);
        assert!(b[0].forward_volume.is_nan() && b[1].forward_volume.is_finite());
        // Cycles from t = 0.8 (closed): [0.8, 1.8] whole, one opening and one closing in it.
        let shifted = cycles(&t, &q, Some(&force), &CycleQuantities::default(), 1.0, 0.8);
        assert_eq!(shifted.len(), 1);
        assert!((shifted[0].opening_time - 0.3).abs() < 1e-9 && (shifted[0].closing_time - 0.8).abs() < 1e-9, "{shifted:?}");
        assert!((shifted[0].forward_volume - c[1].forward_volume).abs() < 1e-12);
    }
}
