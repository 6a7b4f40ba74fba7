//! What a lossy serial link and a misbehaving platform do to a recorded
//! stream (`host-sim record --drop-burst … --bit-flips …`), to measure that
//! lost data loses only itself.
//!
//! Applied in this order, each with its own seeded random stream (so one
//! impairment does not change where another strikes):
//! 0. accelerometer defects the model does not know of ([`AccelDefects`]):
//!    more noise than the platform file says (`--accel-noise-scale K`: the
//!    means get independent extra noise of σ·√(K² − 1), K× in all) and a
//!    constant bias in the instrument frame (`--accel-bias-ug X,Y,Z`, µg),
//!    which is not applied here but added to the scenario's accelerometer
//!    bias `ba` ([`AccelDefects::biased`]) so that the truth simulator is the
//!    one place that applies a bias (and the truth sidecar records the sum);
//!    the stream's `Configure` keeps the scenario's noise level;
//! 1. accelerometer outliers on a fraction of the samples (a spike of `k σ`
//!    on one random axis, random sign);
//! 2. clock steps (every timestamp from a sequence number on shifted);
//! 3. lost sample frames: bursts of consecutive ones, and each one at random
//!    with a probability;
//! 4. bit flips in the encoded byte stream (each byte, with a probability,
//!    gets one random bit flipped), after framing.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rollcal::wire::Sample;

use crate::sim::scenario::Scenario;

/// Impairments of a recorded stream (all off by default).
#[derive(clap::Args, Clone, Debug)]
pub struct Impairments {
    /// Drop LEN consecutive sample frames from sequence number START on
    /// (START:LEN; repeatable).
    #[arg(long = "drop-burst", value_name = "START:LEN", value_parser = parse_burst)]
    pub drop_bursts: Vec<(u32, u32)>,
    /// Drop each sample frame with this probability (0..1).
    #[arg(long, value_name = "P", default_value_t = 0.0, value_parser = parse_probability)]
    pub drop_random: f64,
    /// Shift every timestamp from sequence number SEQ on by SECONDS (SEQ:SECONDS;
    /// repeatable): a clock step of the platform computer.
    #[arg(long = "clock-step", value_name = "SEQ:SECONDS", value_parser = parse_clock_step)]
    pub clock_steps: Vec<(u32, f64)>,
    /// Flip one random bit of each byte of the encoded stream with this
    /// probability (0..1), after framing.
    #[arg(long, value_name = "P", default_value_t = 0.0, value_parser = parse_probability)]
    pub bit_flips: f64,
    /// Give this fraction of samples (0..1) an accelerometer outlier.
    #[arg(long, value_name = "P", default_value_t = 0.0, value_parser = parse_probability)]
    pub outliers: f64,
    /// Size of an outlier, in accelerometer σ.
    #[arg(long, value_name = "K", default_value_t = 100.0)]
    pub outlier_sigma: f64,
    /// Unmodelled accelerometer defects (more noise, a constant bias).
    #[command(flatten)]
    pub accel: AccelDefects,
}

/// Accelerometer defects the estimator's model does not know of.
#[derive(clap::Args, Clone, Copy, Debug, PartialEq)]
pub struct AccelDefects {
    /// Accelerometer noise K× the scenario's (K ≥ 1): extra independent
    /// noise σ·√(K² − 1) on every period mean; the stream's `Configure`
    /// (and a CSV log's platform file) keep the scenario's σ.
    #[arg(long, value_name = "K", default_value_t = 1.0, value_parser = parse_scale)]
    pub accel_noise_scale: f64,
    /// A constant accelerometer bias X,Y,Z (µg, instrument frame), added to
    /// the scenario's accelerometer bias (ba_ug of its instruments table;
    /// the truth sidecar records the sum). The installation model does not
    /// model it; the full model (calibrate --errors full) estimates it as
    /// ba.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_triple, allow_hyphen_values = true)]
    pub accel_bias_ug: Option<[f64; 3]>,
}

impl Default for AccelDefects {
    fn default() -> Self {
        Self {
            accel_noise_scale: 1.0,
            accel_bias_ug: None,
        }
    }
}

impl AccelDefects {
    /// Whether any defect is on.
    pub fn any(&self) -> bool {
        self.accel_noise_scale != 1.0 || self.accel_bias_ug.is_some_and(|b| b != [0.0; 3])
    }

    /// The scenario `sc` with the bias added to its accelerometer bias
    /// (`instruments.ba_ug`, µg): the truth simulator applies it to the
    /// noise-free means. Without a bias, `sc` unchanged.
    pub fn biased(&self, sc: &Scenario) -> Scenario {
        let mut out = sc.clone();
        if let Some(b) = self.accel_bias_ug.filter(|b| *b != [0.0; 3]) {
            for (a, d) in out.instruments.ba_ug.iter_mut().zip(b) {
                *a += d;
            }
        }
        out
    }

    /// Whether the stream needs per-sample offsets (extra noise).
    fn extra_noise(&self) -> bool {
        self.accel_noise_scale != 1.0
    }

    /// The extra noise (g) to add to `n` consecutive accelerometer means of
    /// noise σ `sigma_accel` (g), seeded by `seed`. The bias is not among
    /// them: it is the scenario's ([`Self::biased`]).
    pub fn offsets(&self, n: usize, sigma_accel: f64, seed: u64) -> Vec<[f64; 3]> {
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6163_6365_6c64_6566);
        let extra = sigma_accel * (self.accel_noise_scale.powi(2) - 1.0).max(0.0).sqrt();
        (0..n)
            .map(|_| {
                let mut o = [0.0; 3];
                if extra > 0.0 {
                    for v in &mut o {
                        let e: f64 = StandardNormal.sample(&mut rng);
                        *v += extra * e;
                    }
                }
                o
            })
            .collect()
    }
}

fn parse_scale(s: &str) -> Result<f64, String> {
    let k: f64 = s.parse().map_err(|_| format!("'{s}' is not a number"))?;
    if k.is_finite() && (1.0..=1e3).contains(&k) {
        Ok(k)
    } else {
        Err(format!("noise scale {k} is not in [1, 1000]"))
    }
}

fn parse_triple(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("'{s}' is not X,Y,Z (three numbers)"))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite() && c.abs() <= 1e5) => Ok([*x, *y, *z]),
        _ => Err(format!(
            "'{s}' is not X,Y,Z (three finite numbers, at most 1e5 µg each)"
        )),
    }
}

impl Default for Impairments {
    /// All off; outliers, when switched on, of 100σ (as the CLI's default).
    fn default() -> Self {
        Self {
            drop_bursts: Vec::new(),
            drop_random: 0.0,
            clock_steps: Vec::new(),
            bit_flips: 0.0,
            outliers: 0.0,
            outlier_sigma: 100.0,
            accel: AccelDefects::default(),
        }
    }
}

/// What [`Impairments`] did, for the log line and the tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Applied {
    /// Sample frames dropped.
    pub dropped: usize,
    /// Samples given an outlier.
    pub outliers: usize,
    /// Samples whose timestamp was shifted.
    pub shifted: usize,
    /// Bits flipped in the byte stream.
    pub bit_flips: usize,
}

fn parse_probability(s: &str) -> Result<f64, String> {
    let p: f64 = s.parse().map_err(|_| format!("'{s}' is not a number"))?;
    if (0.0..=1.0).contains(&p) {
        Ok(p)
    } else {
        Err(format!("{p} is not a probability in [0, 1]"))
    }
}

fn parse_pair<A: std::str::FromStr, B: std::str::FromStr>(
    s: &str,
    what: &str,
) -> Result<(A, B), String> {
    let (a, b) = s
        .split_once(':')
        .ok_or_else(|| format!("'{s}' is not {what}"))?;
    match (a.trim().parse(), b.trim().parse()) {
        (Ok(a), Ok(b)) => Ok((a, b)),
        _ => Err(format!("'{s}' is not {what}")),
    }
}

fn parse_burst(s: &str) -> Result<(u32, u32), String> {
    parse_pair(s, "START:LEN (two unsigned integers)")
}

fn parse_clock_step(s: &str) -> Result<(u32, f64), String> {
    let (seq, dt): (u32, f64) = parse_pair(s, "SEQ:SECONDS")?;
    if dt.is_finite() && dt.abs() < 1e6 {
        Ok((seq, dt))
    } else {
        Err(format!(
            "clock step {dt} s is not a finite number below 1e6 s"
        ))
    }
}

impl Impairments {
    /// Whether any impairment is on.
    pub fn any(&self) -> bool {
        !self.drop_bursts.is_empty()
            || self.drop_random > 0.0
            || !self.clock_steps.is_empty()
            || self.bit_flips > 0.0
            || self.outliers > 0.0
            || self.accel.any()
    }

    /// Steps 0–3 on the samples of a run (accelerometer noise σ `sigma_accel`
    /// g), seeded by `seed`; the accelerometer bias is already in the
    /// samples (the scenario simulated was [`AccelDefects::biased`]).
    pub fn apply_to_samples(
        &self,
        samples: &mut Vec<Sample>,
        sigma_accel: f64,
        seed: u64,
        applied: &mut Applied,
    ) {
        if self.accel.extra_noise() {
            let offsets = self.accel.offsets(samples.len(), sigma_accel, seed);
            for (s, o) in samples.iter_mut().zip(offsets) {
                for (a, d) in s.accel_mean.iter_mut().zip(o) {
                    *a = (f64::from(*a) + d) as f32;
                }
            }
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6f75_746c_6965_7273);
        if self.outliers > 0.0 {
            for s in samples.iter_mut() {
                if rng.gen_bool(self.outliers) {
                    let axis = rng.gen_range(0..3);
                    let sign = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
                    if let Some(a) = s.accel_mean.get_mut(axis) {
                        *a = (f64::from(*a) + sign * self.outlier_sigma * sigma_accel) as f32;
                    }
                    applied.outliers += 1;
                }
            }
        }
        for (from, dt) in &self.clock_steps {
            let shift_us = (dt * 1e6).round() as i64;
            for s in samples.iter_mut().filter(|s| s.seq >= *from) {
                s.t_us = s.t_us.saturating_add_signed(shift_us);
                applied.shifted += 1;
            }
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6472_6f70_7065_6421);
        let before = samples.len();
        samples.retain(|s| {
            let in_burst = self
                .drop_bursts
                .iter()
                .any(|(start, len)| s.seq >= *start && s.seq - start < *len);
            let random = self.drop_random > 0.0 && rng.gen_bool(self.drop_random);
            !(in_burst || random)
        });
        applied.dropped += before - samples.len();
    }

    /// Step 4 on the encoded stream, seeded by `seed`.
    pub fn apply_to_bytes(&self, bytes: &mut [u8], seed: u64, applied: &mut Applied) {
        if self.bit_flips <= 0.0 {
            return;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6269_7466_6c69_7073);
        for b in bytes.iter_mut() {
            if rng.gen_bool(self.bit_flips) {
                *b ^= 1 << rng.gen_range(0..8);
                applied.bit_flips += 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples(n: u32) -> Vec<Sample> {
        (1..=n)
            .map(|seq| Sample {
                seq,
                t_us: u64::from(seq) * 1_000_000,
                dt: 1.0,
                dtheta_cmd: [0.0; 3],
                accel_mean: [0.0, 1.0, 0.0],
                gimbal: None,
                c_cn_quat: [1.0, 0.0, 0.0, 0.0],
            })
            .collect()
    }

    #[test]
    fn bursts_clock_steps_and_outliers_do_what_they_say() {
        let imp = Impairments {
            drop_bursts: vec![(10, 5)],
            clock_steps: vec![(50, 2.0)],
            outliers: 0.1,
            ..Impairments::default()
        };
        let mut s = samples(100);
        let mut applied = Applied::default();
        imp.apply_to_samples(&mut s, 1e-6, 1, &mut applied);
        assert_eq!(applied.dropped, 5);
        assert!(s.iter().all(|x| !(10..15).contains(&x.seq)));
        assert_eq!(applied.shifted, 51);
        let at = |seq: u32| s.iter().find(|x| x.seq == seq).map(|x| x.t_us);
        assert_eq!(at(50), Some(52_000_000));
        assert_eq!(at(49), Some(49_000_000));
        let spiked = s.iter().filter(|x| x.accel_mean != [0.0, 1.0, 0.0]).count();
        // (Outliers are drawn before the burst drops its 5 samples.)
        assert!(spiked <= applied.outliers && applied.outliers - spiked <= 5);
        assert!((3..=20).contains(&spiked), "{spiked}");
    }

    #[test]
    fn random_loss_and_bit_flips_hit_their_rate() {
        let imp = Impairments {
            drop_random: 0.5,
            bit_flips: 1e-3,
            ..Impairments::default()
        };
        let mut s = samples(10_000);
        let mut applied = Applied::default();
        imp.apply_to_samples(&mut s, 1e-6, 2, &mut applied);
        assert!((4_700..5_300).contains(&applied.dropped), "{applied:?}");
        let mut bytes = vec![0u8; 100_000];
        imp.apply_to_bytes(&mut bytes, 2, &mut applied);
        assert!((80..120).contains(&applied.bit_flips), "{applied:?}");
        assert_eq!(
            bytes.iter().map(|b| b.count_ones() as usize).sum::<usize>(),
            applied.bit_flips
        );
    }

    #[test]
    fn bad_arguments_are_refused() {
        assert!(parse_probability("1.5").is_err());
        assert!(parse_probability("x").is_err());
        assert!(parse_burst("10").is_err());
        assert!(parse_burst("10:-1").is_err());
        assert!(parse_clock_step("5:inf").is_err());
        assert_eq!(parse_clock_step("1801:2.5"), Ok((1801, 2.5)));
        assert!(parse_scale("0.5").is_err() && parse_scale("nan").is_err());
        assert_eq!(parse_triple("10, 0,-3"), Ok([10.0, 0.0, -3.0]));
        assert!(parse_triple("1,2").is_err() && parse_triple("1,2,inf").is_err());
    }

    #[test]
    fn accel_defects_add_the_bias_to_the_scenario_and_the_extra_noise() {
        let d = AccelDefects {
            accel_noise_scale: 3.0,
            accel_bias_ug: Some([10.0, 0.0, -5.0]),
        };
        let mut sc = Scenario::paper();
        sc.instruments.ba_ug = [30.0, -20.0, 45.0];
        assert_eq!(d.biased(&sc).instruments.ba_ug, [40.0, -20.0, 40.0]);
        assert_eq!(AccelDefects::default().biased(&sc), sc);
        let o = d.offsets(20_000, 1e-6, 1);
        for c in 0..3 {
            let m = o.iter().map(|v| v[c]).sum::<f64>() / o.len() as f64;
            let var = o.iter().map(|v| (v[c] - m).powi(2)).sum::<f64>() / o.len() as f64;
            assert!(m.abs() < 1e-7, "{c}: mean {m}");
            // Extra variance 8σ²: 9σ² in all with the simulator's σ².
            assert!((var / 8e-12 - 1.0).abs() < 0.05, "{c}: var {var}");
        }
        assert!(!AccelDefects::default().any());
        assert!(AccelDefects::default().offsets(3, 1e-6, 1) == vec![[0.0; 3]; 3]);
    }
}
