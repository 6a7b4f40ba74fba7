//! The truth simulator (docs/model.md §Installation models, §Measurement
//! timing): integrates the physical platform.
//!
//! It integrates the platform attitude `C^ps_n` under the true gyros
//! (`ω^ps_ip = G [(I + K_g) ωc + ε] + w_g`, `ε = dg + D_g f^ps` plus the
//! drift's wandering parts; docs/model.md §Instrument errors, §Errors that
//! wander), the computed frame `C^c_n` under the rolling path, and the
//! commanded increment `∫ωc dt`, all by RK4 at the truth step (0.01 s), and
//! applies the true accelerometers (`Z_a = ba + (I + K_a) u + K2 (u ∘ u)`,
//! `u = A f^ps`, plus the bias's wandering parts) to the true specific
//! force. The wandering parts (Gauss–Markov, random walk, warm-up) move at
//! the truth step ([`WanderTruth`]). With every instrument error zero it
//! takes exactly the installation-only arithmetic (`G ωc`, `A f^ps`), bit
//! for bit. It shares with the estimator only the
//! tested geometry primitives (`skew`, `dcm`, `gimbal_dcm`, `euler_angles`,
//! `rotation_vector`, `wrap_angle`); it uses none of the configurations'
//! state models, dynamics or measurement functions.

use nalgebra::{Matrix3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rollcal::geometry::{
    dcm, euler_angles, gimbal_dcm, rotation_vector, skew, wrap_angles, EARTH_RATE,
};
use rollcal::models::{AttitudeKind, ConfigId, PlatformFrame};

use crate::sim::instruments::{DEG_H, PPM, UG};
use crate::sim::scenario::{Instruments, Scenario, ARCSEC, DEG};
use crate::sim::wander::{WanderProcess, WanderTruth};

/// True parameters in radians, ps frame, plus the exactly derived pa values,
/// and the instruments' own errors in internal units (docs/model.md
/// §Instrument errors).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TruthParams {
    /// θaT (rad).
    pub theta_a_t: Vector3<f64>,
    /// θaC (rad).
    pub theta_a_c: Vector3<f64>,
    /// θgT (rad).
    pub theta_g_t: Vector3<f64>,
    /// θgC in the ps frame (rad).
    pub theta_g_c: Vector3<f64>,
    /// θgC^pa, exactly `R(θgC^pa) = R(−θaC) R(θgC)` (rad).
    pub theta_g_c_pa: Vector3<f64>,
    /// λ (rad).
    pub lambda: Vector3<f64>,
    /// θA(0) (rad).
    pub gimbal0: Vector3<f64>,
    /// Constant gyro drift `dg` per gyro (rad/s).
    pub dg: Vector3<f64>,
    /// g-sensitive gyro drift `D_g` (rad/s per g; row = gyro, column = axis
    /// of the specific force in ps).
    pub d_g: Matrix3<f64>,
    /// Gyro scale-factor errors `kg` (dimensionless).
    pub kg: Vector3<f64>,
    /// Accelerometer bias `ba` (g, accelerometer output axes).
    pub ba: Vector3<f64>,
    /// Accelerometer scale-factor errors `ka` (dimensionless).
    pub ka: Vector3<f64>,
    /// Accelerometer second-order coefficients `k2` (g per g²).
    pub k2: Vector3<f64>,
    /// The errors that wander (internal units; docs/model.md §Errors that
    /// wander).
    pub wander: rollcal::models::Wander<f64>,
    /// The warm-up of the drift, `Δ_g` (rad/s), of the bias, `Δ_a` (g),
    /// and its time constant τ_w (s; 0: none).
    pub warmup: (Vector3<f64>, Vector3<f64>, f64),
}

impl TruthParams {
    /// From a scenario.
    pub fn from_scenario(s: &Scenario) -> Self {
        let v = |a: [f64; 3]| Vector3::new(a[0], a[1], a[2]) * DEG;
        let t = &s.truth;
        let theta_a_c = v(t.theta_a_c_deg);
        let theta_g_c = v(t.theta_g_c_deg);
        // Written out here rather than calling the crate's instruments module.
        let theta_g_c_pa = rotation_vector(&(dcm(&(-theta_a_c)) * dcm(&theta_g_c)));
        Self {
            theta_a_t: v(t.theta_a_t_deg),
            theta_a_c,
            theta_g_t: v(t.theta_g_t_deg),
            theta_g_c,
            theta_g_c_pa,
            lambda: v(t.lambda_deg),
            gimbal0: v(t.gimbal0_deg),
            ..Self::instruments_of(&s.instruments)
        }
    }

    /// Zero installation errors and the instrument errors of `ins`, converted
    /// from the file's units (°/h, °/h/g, ppm, µg) to rad/s, rad/s/g, 1, g.
    fn instruments_of(ins: &Instruments) -> Self {
        let v = |a: [f64; 3], unit: f64| Vector3::new(a[0], a[1], a[2]) * unit;
        let d = &ins.d_g_deg_h_g;
        let z = Vector3::zeros();
        Self {
            theta_a_t: z,
            theta_a_c: z,
            theta_g_t: z,
            theta_g_c: z,
            theta_g_c_pa: z,
            lambda: z,
            gimbal0: z,
            dg: v(ins.dg_deg_h, DEG_H),
            d_g: Matrix3::from_fn(|r, c| d[r][c]) * DEG_H,
            kg: v(ins.kg_ppm, PPM),
            ba: v(ins.ba_ug, UG),
            ka: v(ins.ka_ppm, PPM),
            k2: v(ins.k2_ug_g2, UG),
            wander: ins.wander.to_model(),
            warmup: (
                v(ins.warmup.gyro_deg_h, DEG_H),
                v(ins.warmup.accel_ug, UG),
                ins.warmup.time_constant_s,
            ),
        }
    }

    /// Whether any instrument error (`dg`, `D_g`, `kg`, `ba`, `ka`, `k2`,
    /// a wandering part) is non-zero; without one the simulator runs the
    /// installation-only arithmetic.
    pub fn has_instrument_errors(&self) -> bool {
        let z3 = Vector3::zeros();
        self.dg != z3
            || self.d_g != Matrix3::zeros()
            || self.kg != z3
            || self.ba != z3
            || self.ka != z3
            || self.k2 != z3
            || self.has_wander()
    }

    /// Whether the drift or the bias wander (a Gauss–Markov part, a random
    /// walk or a warm-up).
    pub fn has_wander(&self) -> bool {
        !self.wander.is_none()
            || self.warmup.0 != Vector3::zeros()
            || self.warmup.1 != Vector3::zeros()
    }

    /// The gyros' input in the bracket of the gyro model,
    /// `(I + K_g) ωc + dg + D_g f^ps` (rad/s, gyro axes), for the command
    /// `omega_c` (rad/s) and the specific force `f_ps` (g, ps frame); the
    /// platform rate is `G` times it (plus noise). The constant drift only:
    /// [`TruthParams::gyro_input_with`] adds its wandering parts.
    pub fn gyro_input(&self, omega_c: &Vector3<f64>, f_ps: &Vector3<f64>) -> Vector3<f64> {
        omega_c + omega_c.component_mul(&self.kg) + self.dg + self.d_g * f_ps
    }

    /// [`TruthParams::gyro_input`] with the drift's wandering parts
    /// `extra` (rad/s) added to `dg`.
    pub fn gyro_input_with(
        &self,
        omega_c: &Vector3<f64>,
        f_ps: &Vector3<f64>,
        extra: &Vector3<f64>,
    ) -> Vector3<f64> {
        omega_c + omega_c.component_mul(&self.kg) + (self.dg + extra) + self.d_g * f_ps
    }

    /// The accelerometers' intrinsic errors applied to an installation-only
    /// output `z = A f^ps` (g) at one instant: `ba + (I + K_a) z + K2 (z ∘ z)`
    /// (g).
    pub fn accel_intrinsic(&self, z: &Vector3<f64>) -> Vector3<f64> {
        self.accel_intrinsic_of_means(z, &z.component_mul(z), &Vector3::zeros())
    }

    /// The accelerometers' intrinsic errors of a period's mean: `ba + b̄ +
    /// (I + K_a) z̄ + K2 (z∘z)‾` from the mean installation-only output
    /// `mean_z` (g), the mean of its element-wise square `mean_z_sq` (g²)
    /// and the mean of the bias's wandering parts `mean_extra` (g): exact
    /// for means over the same nodes (the output is affine in `z`, `z ∘ z`
    /// and the bias).
    pub fn accel_intrinsic_of_means(
        &self,
        mean_z: &Vector3<f64>,
        mean_z_sq: &Vector3<f64>,
        mean_extra: &Vector3<f64>,
    ) -> Vector3<f64> {
        let out = self.ba + mean_z + mean_z.component_mul(&self.ka);
        let out = if self.k2 == Vector3::zeros() {
            out
        } else {
            out + self.k2.component_mul(mean_z_sq)
        };
        if *mean_extra == Vector3::zeros() {
            out
        } else {
            out + mean_extra
        }
    }

    /// The noise-free accelerometer output `ba + (I + K_a) u + K2 (u ∘ u)`,
    /// `u = A f^ps` (g), for the specific force `f_ps` (g, ps frame); the
    /// constant bias only.
    pub fn accel_output(&self, f_ps: &Vector3<f64>) -> Vector3<f64> {
        self.accel_intrinsic(&(self.a() * f_ps))
    }

    /// The g-sensitive drift in the pa frame, `D_g^pa = D_g R(θaC)` (rad/s
    /// per g; column = axis of the specific force in pa), exactly: with
    /// `f^pa = R(−θaC) f^ps`, `D_g f^ps = D_g R(θaC) f^pa`.
    pub fn d_g_pa(&self) -> Matrix3<f64> {
        self.d_g * dcm(&self.theta_a_c)
    }

    fn lower(t: &Vector3<f64>) -> Matrix3<f64> {
        Matrix3::new(0.0, 0.0, 0.0, t.x, 0.0, 0.0, t.y, t.z, 0.0)
    }

    /// True gyro matrix `G = R(θgC)(I + L(θgT))` (ps).
    pub fn g(&self) -> Matrix3<f64> {
        dcm(&self.theta_g_c) * (Matrix3::identity() + Self::lower(&self.theta_g_t))
    }

    /// True accelerometer matrix `A = (I + L(θaT)) R(−θaC)` (ps).
    pub fn a(&self) -> Matrix3<f64> {
        (Matrix3::identity() + Self::lower(&self.theta_a_t)) * dcm(&(-self.theta_a_c))
    }
}

/// The true platform at one instant `t_k`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instant {
    /// Time (s).
    pub t: f64,
    /// True platform attitude `C^ps_n`.
    pub c_ps_n: Matrix3<f64>,
    /// Computed frame `C^c_n`.
    pub c_c_n: Matrix3<f64>,
    /// Noise-free accelerometer output at `t` (g).
    pub accel_at_t: Vector3<f64>,
    /// Noise-free gimbal angles at `t`, wrapped (rad).
    pub gimbal: Vector3<f64>,
}

/// One filter period `[t_{k−1}, t_k]` as the platform computer sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeriodSample {
    /// Period index k ≥ 1 (the sample at `t_k`).
    pub k: u32,
    /// Period length (s).
    pub dt: f64,
    /// Commanded angle increment over the period (rad, c frame).
    pub dtheta_cmd: Vector3<f64>,
    /// Mean accelerometer output over the period with noise (g).
    pub accel_mean: Vector3<f64>,
    /// Gimbal angles at `t_k` with noise, wrapped (rad).
    pub gimbal: Vector3<f64>,
    /// Noise-free mean accelerometer output (g).
    pub accel_mean_clean: Vector3<f64>,
    /// The true platform at `t_k`.
    pub truth: Instant,
    /// The wandering parts of the drift and the bias at `t_k` (zero
    /// without them).
    pub wander: WanderTruth,
}

/// A simulated run.
#[derive(Clone, Debug)]
pub struct Simulation {
    /// True parameters.
    pub params: TruthParams,
    /// Earth rate `ω^n_ie` used (rad/s).
    pub earth_rate_n: Vector3<f64>,
    /// The true platform at t = 0.
    pub initial: Instant,
    /// The wandering parts at t = 0 (zero without them).
    pub initial_wander: WanderTruth,
    /// One sample per period.
    pub samples: Vec<PeriodSample>,
}

impl Simulation {
    /// The wandering parts of the drift and the bias at the end of the
    /// run (zero without them): with the constants, the calibrated values
    /// of docs/model.md §Errors that wander.
    pub fn final_wander(&self) -> WanderTruth {
        self.samples
            .last()
            .map_or_else(WanderTruth::zero, |s| s.wander)
    }
}

/// Simulation switches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimOptions {
    /// RNG seed.
    pub seed: u64,
    /// Add noise (false: the golden, noise-free run).
    pub noise: bool,
    /// Earth rate on (and-ed with the scenario's).
    pub earth_rate: bool,
}

#[derive(Clone, Copy)]
struct State {
    c_ps_n: Matrix3<f64>,
    c_c_n: Matrix3<f64>,
    dtheta: Vector3<f64>,
}

struct Deriv {
    c_ps_n: Matrix3<f64>,
    c_c_n: Matrix3<f64>,
    dtheta: Vector3<f64>,
}

fn axpy(s: &State, d: &Deriv, h: f64) -> State {
    State {
        c_ps_n: s.c_ps_n + d.c_ps_n * h,
        c_c_n: s.c_c_n + d.c_c_n * h,
        dtheta: s.dtheta + d.dtheta * h,
    }
}

/// Piecewise-constant path rate `ω^n_path` (rad/s) over time.
struct Path {
    /// (end time, rate vector) per segment.
    segments: Vec<(f64, Vector3<f64>)>,
}

impl Path {
    fn new(s: &Scenario) -> Self {
        let mut t = 0.0;
        let mut segments = Vec::with_capacity(s.path.len());
        for seg in &s.path {
            let u = seg.axis.unit().unwrap_or([0.0; 3]);
            t += seg.rotation_s();
            segments.push((t, Vector3::new(u[0], u[1], u[2]) * (seg.rate_deg_s * DEG)));
            // A dwell: zero path rate until its end.
            if seg.dwell_s > 0.0 {
                t += seg.dwell_s;
                segments.push((t, Vector3::zeros()));
            }
        }
        Self { segments }
    }

    /// Rate over the step starting at `t0` (steps never straddle a boundary).
    fn rate(&self, t0: f64) -> Vector3<f64> {
        self.segments
            .iter()
            .find(|(end, _)| t0 < *end - 1e-9)
            .map_or_else(Vector3::zeros, |(_, w)| *w)
    }
}

/// The largest middle gimbal angle |β| (°) a simulated path may reach for a
/// configuration that measures the gimbal angles (M2). At gimbal lock
/// (|β| = 90°) the outer and inner angles α, γ are singular: only α ± γ is
/// defined, and near it their sensitivity to the attitude grows as 1/cos β.
/// Measured on M2-ps (`host-sim run` on paths that turn about Up to the
/// given β): up to |β| = 84.7° every update of the last pass is accepted, at
/// 87.4° 1–2 of 540 are already gated, and a path that reaches 89.5°
/// (90° about South, then 90° about East) diverges (σ to 1e26″, mean NIS
/// in the thousands). 85° keeps the sensitivity ≤ 11.5×.
/// (`host-sim design` keeps to 60° by default, `--max-beta-deg`.)
pub const MAX_GIMBAL_BETA_DEG: f64 = 85.0;

/// A simulated path that comes closer to gimbal lock than
/// [`MAX_GIMBAL_BETA_DEG`] for a configuration that measures the gimbal
/// angles ([`check_gimbal_lock`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GimbalLockError {
    /// The configuration.
    pub config: ConfigId,
    /// The largest |β| of the path (rad).
    pub beta_rad: f64,
    /// When it is reached (s).
    pub t_s: f64,
}

impl std::fmt::Display for GimbalLockError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let id = self.config;
        write!(
            f,
            "the path comes within {:.1}° of gimbal lock (|β| = {:.1}° at t = {:.0} s): {id} measures the gimbal angles, which are singular there; keep |β| ≤ {MAX_GIMBAL_BETA_DEG}° (host-sim design keeps it ≤ 60° by default)",
            90.0 - self.beta_rad / DEG,
            self.beta_rad / DEG,
            self.t_s
        )
    }
}

impl std::error::Error for GimbalLockError {}

/// Refuses a simulated path that comes closer to gimbal lock than
/// [`MAX_GIMBAL_BETA_DEG`] when configuration `id` measures the gimbal
/// angles; any path for the others (they do not use the gimbal angles).
pub fn check_gimbal_lock(id: ConfigId, sim: &Simulation) -> Result<(), GimbalLockError> {
    if id.layout().z() != 6 {
        return Ok(());
    }
    let worst = sim
        .samples
        .iter()
        .map(|s| (s.truth.gimbal.y.abs(), s.truth.t))
        .fold((0.0, 0.0), |a, b| if b.0 > a.0 { b } else { a });
    if worst.0 > MAX_GIMBAL_BETA_DEG * DEG {
        return Err(GimbalLockError {
            config: id,
            beta_rad: worst.0,
            t_s: worst.1,
        });
    }
    Ok(())
}

/// What drives the platform over a period: the path, the Earth rate
/// `ω^n_ie`, the true gyro and accelerometer matrices `G`, `A`, the
/// specific force `f^n`, the period's gyro noise rate and the instrument
/// errors (`None` when all are zero: the installation-only arithmetic).
struct Dynamics<'a> {
    path: &'a Path,
    w_ie: Vector3<f64>,
    g: Matrix3<f64>,
    a: Matrix3<f64>,
    f_n: Vector3<f64>,
    w_gyro: Vector3<f64>,
    instruments: Option<&'a TruthParams>,
}

impl Dynamics<'_> {
    /// The gyros' input for the command `w_c` at attitude `c_ps_n`:
    /// `(I + K_g) ωc + dg + D_g f^ps` with `f^ps = C^ps_n f^n` (evaluated at
    /// each RK4 stage, since it moves with the attitude) and the drift's
    /// wandering parts `extra` (held over the truth step), or `ωc` itself
    /// without instrument errors.
    fn gyro_input(
        &self,
        w_c: Vector3<f64>,
        c_ps_n: &Matrix3<f64>,
        extra: Option<&Vector3<f64>>,
    ) -> Vector3<f64> {
        match (self.instruments, extra) {
            (Some(p), None) => p.gyro_input(&w_c, &(c_ps_n * self.f_n)),
            (Some(p), Some(e)) => p.gyro_input_with(&w_c, &(c_ps_n * self.f_n), e),
            (None, _) => w_c,
        }
    }
}

/// What [`integrate_period`] sums over the nodes of a period with
/// Simpson's weights: the installation-only accelerometer output, its
/// element-wise square (for `k2`) and the bias's wandering parts.
struct NodeSums {
    z: Vector3<f64>,
    z_sq: Vector3<f64>,
    bias: Vector3<f64>,
}

/// Integrates one period `[t0, t0 + nsub·h]` by RK4 in `nsub` substeps of
/// `h`, advancing `st` (and the wandering parts `wander`, at each substep);
/// returns the Simpson sums over the substep nodes (weights 1, 4, 2, …,
/// 4, 1) of the noise-free installation-only accelerometer output, of its
/// square and of the bias's wandering parts.
fn integrate_period(
    st: &mut State,
    d: &Dynamics<'_>,
    t0: f64,
    h: f64,
    nsub: usize,
    mut wander: Option<&mut WanderProcess>,
) -> NodeSums {
    // Composite Simpson over the substep nodes for the mean accelerometer output.
    let z0 = d.a * st.c_ps_n * d.f_n;
    let mut sums = NodeSums {
        z: z0,
        z_sq: z0.component_mul(&z0),
        bias: wander.as_ref().map_or_else(Vector3::zeros, |w| w.bias(t0)),
    };
    for j in 0..nsub {
        let ts = t0 + j as f64 * h;
        let w_path = d.path.rate(ts);
        let drift = wander.as_ref().map(|w| w.drift(ts));
        let deriv = |x: &State| {
            let w_c = x.c_c_n * (d.w_ie + w_path);
            let w_ps_np =
                d.g * d.gyro_input(w_c, &x.c_ps_n, drift.as_ref()) + d.w_gyro - x.c_ps_n * d.w_ie;
            Deriv {
                c_ps_n: -skew(&w_ps_np) * x.c_ps_n,
                c_c_n: -skew(&(x.c_c_n * w_path)) * x.c_c_n,
                dtheta: w_c,
            }
        };
        let k1 = deriv(&*st);
        let k2 = deriv(&axpy(st, &k1, h / 2.0));
        let k3 = deriv(&axpy(st, &k2, h / 2.0));
        let k4 = deriv(&axpy(st, &k3, h));
        *st = State {
            c_ps_n: st.c_ps_n + (k1.c_ps_n + (k2.c_ps_n + k3.c_ps_n) * 2.0 + k4.c_ps_n) * (h / 6.0),
            c_c_n: st.c_c_n + (k1.c_c_n + (k2.c_c_n + k3.c_c_n) * 2.0 + k4.c_c_n) * (h / 6.0),
            dtheta: st.dtheta + (k1.dtheta + (k2.dtheta + k3.dtheta) * 2.0 + k4.dtheta) * (h / 6.0),
        };
        let weight = if j + 1 == nsub {
            1.0
        } else if j % 2 == 0 {
            4.0
        } else {
            2.0
        };
        let z = d.a * st.c_ps_n * d.f_n;
        sums.z += z * weight;
        if let Some(w) = wander.as_deref_mut() {
            w.advance(h);
            sums.z_sq += z.component_mul(&z) * weight;
            sums.bias += w.bias(ts + h) * weight;
        } else if d.instruments.is_some_and(|p| p.k2 != Vector3::zeros()) {
            sums.z_sq += z.component_mul(&z) * weight;
        }
    }
    sums
}

/// Runs the truth simulator over a scenario.
pub fn simulate(s: &Scenario, opts: SimOptions) -> Simulation {
    let params = TruthParams::from_scenario(s);
    let omega = if s.site.earth_rate && opts.earth_rate {
        EARTH_RATE
    } else {
        0.0
    };
    let lat = s.site.latitude_deg * DEG;
    let w_ie = Vector3::new(omega * lat.cos(), omega * lat.sin(), 0.0);
    let f_n = Vector3::new(0.0, 1.0, 0.0);
    let g = params.g();
    let a = params.a();
    let c_r_n = dcm(&params.lambda);
    let path = Path::new(s);
    let dt = s.timing.period_s;
    let nsub = s.substeps();
    let h = dt / nsub as f64;

    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let unit = Normal::new(0.0, 1.0).unwrap_or_else(|_| unreachable!());
    let mut gauss3 = |sigma: f64| -> Vector3<f64> {
        if opts.noise {
            Vector3::new(
                unit.sample(&mut rng),
                unit.sample(&mut rng),
                unit.sample(&mut rng),
            ) * sigma
        } else {
            Vector3::zeros()
        }
    };
    let sigma_gyro = s.noise.gyro_deg_h * DEG / 3600.0;
    let sigma_accel = s.noise.accel_g;
    let sigma_gimbal = s.noise.gimbal_arcsec * ARCSEC;

    let instruments = params.has_instrument_errors().then_some(&params);
    // The wandering parts: their own random stream (stream 1 of the seed),
    // so that the noise of a scenario without them is what it always was.
    let mut wander = params
        .has_wander()
        .then(|| WanderProcess::new(&params, opts.seed, opts.noise));
    // The accelerometers' bias, scale factor and second-order term on
    // Simpson means of the installation-only output, of its square and of
    // the bias's wandering parts (the weights sum to the mean's divisor, so
    // applying them to the means is exact).
    let intrinsic = |z: Vector3<f64>, z_sq: Vector3<f64>, bias: Vector3<f64>| match instruments {
        Some(p) => p.accel_intrinsic_of_means(&z, &z_sq, &bias),
        None => z,
    };
    let instant = |t: f64, st: &State, bias: Vector3<f64>| {
        let z = a * st.c_ps_n * f_n;
        Instant {
            t,
            c_ps_n: st.c_ps_n,
            c_c_n: st.c_c_n,
            accel_at_t: intrinsic(z, z.component_mul(&z), bias),
            gimbal: wrap_angles(&euler_angles(&(st.c_ps_n * c_r_n.transpose()))),
        }
    };

    let mut st = State {
        c_ps_n: gimbal_dcm(&params.gimbal0) * c_r_n,
        c_c_n: Matrix3::identity(),
        dtheta: Vector3::zeros(),
    };
    let bias_at =
        |w: &Option<WanderProcess>, t: f64| w.as_ref().map_or_else(Vector3::zeros, |w| w.bias(t));
    let initial = instant(0.0, &st, bias_at(&wander, 0.0));
    let initial_wander = wander
        .as_ref()
        .map_or_else(WanderTruth::zero, |w| w.truth(0.0));
    let mut samples = Vec::with_capacity(s.periods());
    for k in 1..=s.periods() {
        let t0 = (k - 1) as f64 * dt;
        let w_gyro = gauss3(sigma_gyro);
        st.dtheta = Vector3::zeros();
        let sums = integrate_period(
            &mut st,
            &Dynamics {
                path: &path,
                w_ie,
                g,
                a,
                f_n,
                w_gyro,
                instruments,
            },
            t0,
            h,
            nsub,
            wander.as_mut(),
        );
        let divisor = 3.0 * nsub as f64;
        let accel_mean_clean =
            intrinsic(sums.z / divisor, sums.z_sq / divisor, sums.bias / divisor);
        let t = k as f64 * dt;
        let truth = instant(t, &st, bias_at(&wander, t));
        samples.push(PeriodSample {
            k: k as u32,
            dt,
            dtheta_cmd: st.dtheta,
            accel_mean: accel_mean_clean + gauss3(sigma_accel),
            gimbal: wrap_angles(&(truth.gimbal + gauss3(sigma_gimbal))),
            accel_mean_clean,
            truth,
            wander: wander
                .as_ref()
                .map_or_else(WanderTruth::zero, |w| w.truth(t)),
        });
    }
    Simulation {
        params,
        earth_rate_n: w_ie,
        initial,
        initial_wander,
        samples,
    }
}

/// The true value (rad) of every state of configuration `id` at instant
/// `at`, in the configuration's state order: the attitude states follow from
/// the true platform attitude, the pa-frame parameters from the exact
/// composition `R(θgC^pa) = R(−θaC) R(θgC)`.
pub fn truth_state(id: ConfigId, p: &TruthParams, at: &Instant) -> Vec<f64> {
    let layout = id.layout();
    let (c_p_n, g_c) = match layout.frame {
        PlatformFrame::Ps => (at.c_ps_n, p.theta_g_c),
        PlatformFrame::Pa => (dcm(&(-p.theta_a_c)) * at.c_ps_n, p.theta_g_c_pa),
    };
    let att = match layout.attitude {
        AttitudeKind::Misalignment => rotation_vector(&(c_p_n * at.c_c_n.transpose())),
        AttitudeKind::Gimbal => wrap_angles(&euler_angles(&(c_p_n * dcm(&p.lambda).transpose()))),
        AttitudeKind::Attitude => wrap_angles(&euler_angles(&c_p_n)),
    };
    let mut x: Vec<f64> = att
        .iter()
        .chain(g_c.iter())
        .chain(p.theta_g_t.iter())
        .copied()
        .collect();
    if layout.ac().is_some() {
        x.extend(p.theta_a_c.iter());
    }
    x.extend(p.theta_a_t.iter());
    if layout.base {
        x.extend(p.lambda.iter());
    }
    x
}
