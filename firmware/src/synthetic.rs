//! A synthetic workload for instruction counts without input: the platform
//! rolls about South at 0.1°/s in 1 s periods and the instruments report
//! what an error-free platform would (gravity in the computed frame, zero
//! gimbal angles). The numbers are not a calibration, only a load of the
//! same shape as the recorded stream. By default the instruments do not
//! wander here: the full model runs with [`Wander::none`] (its
//! Gauss–Markov and warm-up states have a zero prior σ, not estimated; the
//! state vector is the full model's all the same). With `wander=realistic`
//! it runs with the realistic scenario's figures ([`realistic_wander`]):
//! every state estimated and the wandering errors moved each period, the
//! arithmetic of a realistic period.

use core::mem::{align_of, size_of, MaybeUninit};
use core::ptr::addr_of_mut;
use core::sync::atomic::{AtomicBool, Ordering};

use nalgebra::{SVector, Vector3};
use rollcal::ekf::{Filter, FilterConfig, Observation, Options};
use rollcal::geometry::{earth_rate_n, gravity_n};
use rollcal::models::{Environment, Model, Wander};
use rollcal::session::AnyFilter;
use rollcal::wire::InstrumentPrior;

use crate::marks::{rollcal_mark_period_end, rollcal_mark_period_start};
use crate::{Args, Mode, Real};

/// Earth rate (rad/s).
const EARTH_RATE: f64 = 7.292_115e-5;
const DEG: f64 = core::f64::consts::PI / 180.0;

/// The realistic scenario's errors that wander (`scenarios/realistic.toml`,
/// its data-sheet figures in the filter's units: rad/s, g, s).
pub fn realistic_wander() -> Wander<f64> {
    let deg_h = DEG / 3600.0;
    Wander {
        gyro_markov_sigma: 0.003 * deg_h,
        gyro_markov_tau_s: 600.0,
        gyro_random_walk: 0.002 * deg_h / 60.0,
        accel_markov_sigma: 2e-6,
        accel_markov_tau_s: 900.0,
        accel_random_walk: 1e-6 / 60.0,
        gyro_warmup_sigma: 0.005 * deg_h,
        accel_warmup_sigma: 3e-6,
        warmup_tau_s: 1200.0,
    }
}

/// The paper scenario's noise levels and site (docs/model.md §The paper's
/// scenario), with the errors that wander `wander` (f64 figures).
pub fn filter_config(options: Options, noise_scale: u32, wander: &Wander<f64>) -> FilterConfig<Real> {
    let k = f64::from(noise_scale);
    let c = |v: f64| v as Real;
    FilterConfig {
        env: Environment {
            earth_rate_n: earth_rate_n(EARTH_RATE, 34.25 * DEG),
            gravity_n: gravity_n(),
        },
        sigma_accel: c(1e-6 * k),
        sigma_gyro: c(0.1 * DEG / 3600.0),
        sigma_gimbal: c(10.0 * k * DEG / 3600.0),
        options,
        wander: wander.to_precision(),
    }
}

/// The synthetic run's filter, in static memory: as large as the largest
/// filter this image holds (an `AnyFilter`; 58.8 KB in f64 with the full
/// model's 54 states, more than the firmware's stack). In the `LOG` region
/// of `memory.x` (NOLOAD SSRAM, beside the sample log's device), not in
/// the 256 KiB of `RAM`: the benchmark's filter is not a flight image's
/// static memory. Only [`filter_slot`] touches it.
#[link_section = ".log"]
static mut ARENA: MaybeUninit<AnyFilter<Real>> = MaybeUninit::uninit();

/// Set once [`filter_slot`] has handed out [`ARENA`].
static ARENA_TAKEN: AtomicBool = AtomicBool::new(false);

/// [`ARENA`] as an empty slot for a filter of `M`; `None` on a second call.
fn filter_slot<M: Model<N, Z> + 'static, const N: usize, const Z: usize>(
) -> Option<&'static mut Option<Filter<Real, M, N, Z>>> {
    const {
        assert!(size_of::<Option<Filter<Real, M, N, Z>>>() <= size_of::<AnyFilter<Real>>());
        assert!(align_of::<Option<Filter<Real, M, N, Z>>>() <= align_of::<AnyFilter<Real>>());
    }
    if ARENA_TAKEN.swap(true, Ordering::AcqRel) {
        return None;
    }
    // SAFETY: the flag above makes this the only reference ever made to
    // ARENA, whose size and alignment hold the slot (checked above); the
    // slot is written before the reference is formed.
    unsafe {
        let p = addr_of_mut!(ARENA).cast::<Option<Filter<Real, M, N, Z>>>();
        p.write(None);
        Some(&mut *p)
    }
}

// Not inlined: `run` dispatches to one of these per configuration, and
// their frames must not add up in `main`'s frame (which every run pays).
#[inline(never)]
fn run_model<M: Model<N, Z> + 'static, const N: usize, const Z: usize>(args: &Args) -> bool {
    let options = match args.mode {
        Mode::Plain => Options::plain(),
        _ => Options::default(),
    };
    // 1° for the installation states, the default prior for the instrument
    // terms of the full model (its wandering terms: those of `wander`, 0
    // and not estimated with `Wander::none`).
    let wander = if args.realistic_wander {
        realistic_wander()
    } else {
        Wander::none()
    };
    let installation = M::LAYOUT.installation_n();
    let instruments = InstrumentPrior::default().sigma(&wander);
    let sigma0 = SVector::<Real, N>::from_fn(|i, _| {
        let s = match i.checked_sub(installation) {
            None => 1.0 * DEG,
            Some(k) => instruments.get(k).copied().unwrap_or(1.0 * DEG),
        };
        s as Real
    });
    let Some(slot) = filter_slot::<M, N, Z>() else {
        defmt::error!("the synthetic run's filter is already in use");
        return false;
    };
    // Built straight into its static slot: no filter on the stack.
    let Ok(f) = Filter::new_in(
        slot,
        filter_config(options, args.noise_scale, &wander),
        SVector::zeros(),
        sigma0,
    ) else {
        defmt::error!("invalid filter configuration");
        return false;
    };
    if args.mode == Mode::Linearised {
        f.set_nominal(Some(SVector::zeros()));
    }
    let dt = 1.0;
    let dtheta = Vector3::new(0.0, 0.0, -0.1 * DEG);
    let mut failures = 0u32;
    for k in 0..args.periods {
        let period = f.command_frame().period(&dtheta, dt);
        let [_, _, c_end] = period.c_cn;
        let obs = Observation {
            accel_mean: (c_end * f.config().env.gravity_n).map(|v| v as Real),
            gimbal: Some(Vector3::zeros()),
        };
        rollcal_mark_period_start();
        let r = f.step(&dtheta, dt, &obs);
        rollcal_mark_period_end();
        if let Err(e) = r {
            failures += 1;
            if failures <= 5 {
                defmt::warn!("period {}: {}", k, e);
            }
        }
        if (k + 1) % 100 == 0 {
            defmt::info!("period {}: {} updates", k + 1, f.updates());
        }
    }
    defmt::info!(
        "synthetic run done: {} periods, {} updates, {} failed",
        args.periods,
        f.updates(),
        failures
    );
    failures == 0
}

/// Runs the synthetic workload of `args`; true if every step succeeded
/// (false for a configuration this image does not hold: cargo features
/// `config-*`).
pub fn run(args: &Args) -> bool {
    rollcal::with_built_model!(args.config, args.errors, |M, N, Z| run_model::<M, N, Z>(args), else |other| {
        defmt::error!("{} is not in this firmware image (cargo features config-*)", other);
        false
    })
}
