//! Fuzzes the calibrator through the protocol (`rollcal::session`): a
//! structured run built from the input — maybe a `Configure` (any of the
//! seven configurations, plausible or garbage settings), then up to
//! [`MAX_MESSAGES`] messages: samples of a small noise-free model of the
//! configuration (rollcal's own dynamics and measurement), perturbed by the
//! input, or arbitrary ones; `Reset`, `Configure`, checkpoint requests and
//! restores (as taken, or corrupted), estimate requests, `Finish`, ignored
//! `Estimate`s; and tampering with the sample log (a small [`SliceLog`], so
//! that `LogFull` is reached). An input of zeros is a clean M1-pa run.
//!
//! Every message goes through the wire (`encode` → `FrameDecoder`) on its
//! way in, and every reply on its way out. The session must never panic,
//! and after every message the counters must add up (see `check_sample`,
//! `check_lineage` and `check_session`).
#![no_main]

use std::cell::Cell;
use std::rc::Rc;

use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash};
use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use nalgebra::{RealField, SMatrix, SVector, Vector3};
use rollcal::command::CommandFrame;
use rollcal::estimator::{
    EstimatorOptions, FlashLog, LogError, LogRecord, PackedLayout, SampleLog, SliceLog,
};
use rollcal::geometry::{quaternion_from_dcm, wrap_angles};
use rollcal::models::{ConfigId, Environment, ErrorModel, Layout};
use rollcal::session::{AnyCalibrator, Reply, Session, SessionError};
use rollcal::wire::{
    encode, CalibratorConfig, Checkpoint, Estimate, EstimateKind, FrameDecoder, Message, Progress,
    Sample, SinglePassReason, MAX_FRAME_LEN,
};
use rollcal::{Options, RejectReason};

/// Messages per input (keeps one run cheap).
const MAX_MESSAGES: usize = 128;
/// `Finish` messages per input (each runs the multi-pass estimator).
const MAX_FINISH: u32 = 4;
/// Capacity of the sample log (records).
const LOG_CAP: usize = 64;
/// Largest jump of the sequence number past the last accepted sample.
/// Larger jumps are folded below it: a gap of up to `max_bridge` periods
/// (7200 by default) is searched and predicted period by period, and one of
/// unknown motion predicts up to `MAX_UNKNOWN_GAP_STEPS` (7200) periods:
/// bounded, but slow enough to spend a campaign on (fuzz/README.md).
const MAX_GAP: u32 = 32;

fuzz_target!(|data: &[u8]| {
    let mut u = Unstructured::new(data);
    // Exhausted input reads as zeros, so `rare(u, n)` is false on zeros.
    if rare(&mut u, 4) {
        let _ = run::<f32>(&mut u);
    } else {
        let _ = run::<f64>(&mut u);
    }
});

/// True with probability 1/n (false on a zero byte or an exhausted input).
fn rare(u: &mut Unstructured, n: u8) -> bool {
    u.int_in_range(0..=n - 1)
        .map(|v| v == n - 1)
        .unwrap_or(false)
}

fn pick_config(u: &mut Unstructured) -> Result<ConfigId> {
    Ok(ConfigId::ALL[usize::from(u.int_in_range(0..=6u8)?)])
}

/// A value near `plausible`, or (rarely) a garbage one.
fn value(u: &mut Unstructured, plausible: f64) -> Result<f64> {
    Ok(match u.int_in_range(0..=15u8)? {
        0..=9 => plausible,
        10 => plausible * (1.0 + f64::from(u.int_in_range(-100..=100i8)?) * 1e-2),
        11 => f64::from(u.int_in_range(-3..=3i8)?) * plausible,
        12 => [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][usize::from(u.int_in_range(0..=2u8)?)],
        13 => [0.0, -0.0, f64::MIN_POSITIVE, 1e-300, 1e300, f64::MAX, -1.0]
            [usize::from(u.int_in_range(0..=6u8)?)],
        _ => f64::from_bits(u.arbitrary()?),
    })
}

fn value32(u: &mut Unstructured, plausible: f32) -> Result<f32> {
    Ok(match u.int_in_range(0..=7u8)? {
        0..=2 => plausible + f32::from(u.int_in_range(-100..=100i8)?) * 1e-6,
        3 => plausible * f32::from(u.int_in_range(-3..=3i8)?),
        4 => [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][usize::from(u.int_in_range(0..=2u8)?)],
        5 => [0.0, -0.0, f32::MIN_POSITIVE, 1e30, f32::MAX, 2.5]
            [usize::from(u.int_in_range(0..=5u8)?)],
        _ => f32::from_bits(u.arbitrary()?),
    })
}

/// Settings for `id`: the paper's, rarely perturbed or garbage.
fn settings(u: &mut Unstructured, id: ConfigId) -> Result<CalibratorConfig> {
    let mut s = CalibratorConfig::paper(id);
    // The full model (21 more states) in a quarter of the runs.
    if rare(u, 4) {
        s.errors = ErrorModel::Full;
    }
    s.estimate_every = match u.int_in_range(0..=7u8)? {
        0..=2 => 60,
        3 => 0,
        4 | 5 => u.int_in_range(1..=10)?,
        _ => u.arbitrary()?,
    };
    if rare(u, 2) {
        s.sigma_accel_g = value(u, s.sigma_accel_g)?;
        s.sigma_gyro_rad_s = value(u, s.sigma_gyro_rad_s)?;
        s.sigma_gimbal_rad = value(u, s.sigma_gimbal_rad)?;
        for v in s.earth_rate_n.iter_mut().chain(s.gravity_n.iter_mut()) {
            *v = value(u, *v)?;
        }
        s.prior_sigma_rad = value(u, s.prior_sigma_rad)?;
        let p = &mut s.instrument_prior;
        for v in [
            &mut p.dg_rad_s,
            &mut p.d_g_rad_s_g,
            &mut p.kg,
            &mut p.ba_g,
            &mut p.ka,
        ] {
            *v = value(u, *v)?;
        }
        let l = &mut s.limits;
        l.period_s = value(u, l.period_s)?;
        l.period_tolerance_s = value(u, l.period_tolerance_s)?;
        l.max_accel_g = value(u, l.max_accel_g)?;
        l.max_increment_rad = value(u, l.max_increment_rad)?;
        l.max_gimbal_rad = value(u, l.max_gimbal_rad)?;
        l.frame_tolerance_rad = value(u, l.frame_tolerance_rad)?;
        if rare(u, 4) {
            l.max_bridge = u.arbitrary()?;
        }
        s.options = Options {
            second_order_covariance: !rare(u, 4),
            second_order_mean: rare(u, 4),
            second_order_dynamics: rare(u, 4),
            // Each iteration is another update: keep runs cheap.
            iterations: u.int_in_range(0..=2)?,
            iterate_updates: u.int_in_range(0..=300)?,
            nis_gate: value(u, s.options.nis_gate)?,
        };
    }
    Ok(s)
}

/// A noise-free platform of configuration `layout` rolling at a piecewise
/// constant path rate: rollcal's own dynamics and measurement evaluated on
/// an 18-state vector (unused states zero), so the samples are the ones the
/// filter expects and reach its deep paths.
struct Platform {
    layout: Layout,
    env: Environment<f64>,
    x: SVector<f64, 18>,
    frame: CommandFrame<f64>,
    rate: Vector3<f64>,
    seq: u32,
    t_us: u64,
    dt: f64,
    accel: [f32; 3],
}

impl Platform {
    fn new(u: &mut Unstructured, s: &CalibratorConfig) -> Result<Self> {
        let ok = |v: &[f64; 3]| v.iter().all(|x| x.is_finite() && x.abs() < 10.0);
        let paper = CalibratorConfig::paper(s.config);
        let env = Environment {
            earth_rate_n: Vector3::from(if ok(&s.earth_rate_n) {
                s.earth_rate_n
            } else {
                paper.earth_rate_n
            }),
            gravity_n: Vector3::from(if ok(&s.gravity_n) {
                s.gravity_n
            } else {
                paper.gravity_n
            }),
        };
        let layout = s.config.layout();
        let mut x = SVector::<f64, 18>::zeros();
        // Installation errors and initial attitude up to ~10 arcmin.
        for v in x.iter_mut().take(layout.n()) {
            *v = f64::from(u.arbitrary::<i16>()?) * 1e-7;
        }
        let p = s.limits.period_s;
        Ok(Self {
            layout,
            env,
            x,
            frame: CommandFrame::aligned(env.earth_rate_n),
            rate: Vector3::zeros(),
            seq: u.int_in_range(0..=1000)?,
            t_us: u.int_in_range(0..=1_000_000_000_000)?,
            dt: if p.is_finite() && (1e-3..=10.0).contains(&p) {
                p
            } else {
                1.0
            },
            accel: [0.0, 1.0, 0.0],
        })
    }

    /// Maybe switches the path rate (rad/s, a few hundredths per axis).
    fn steer(&mut self, u: &mut Unstructured) -> Result<()> {
        if self.seq % 16 == 0 || rare(u, 8) {
            let mut r = || -> Result<f64> { Ok(f64::from(u.int_in_range(-3..=3i8)?) * 1e-2) };
            self.rate = Vector3::new(r()?, r()?, r()?);
        }
        Ok(())
    }

    /// Advances one period and returns its sample.
    fn period(&mut self) -> Sample {
        let dtheta = self.frame.increment(&self.rate, self.dt);
        let period = self.frame.period_at_rate(&self.rate, self.dt);
        let m = self.layout.matrices(&self.x);
        let att = self.layout.attitude(&self.x);
        if let Some(prop) = self
            .layout
            .propagate::<f64, 18>(&self.env, &m, &att, &period)
        {
            let mut h = SMatrix::<f64, 3, 18>::zeros();
            let (z, _) = self
                .layout
                .mean_accel(&self.env, &m, &prop, &period, &mut h);
            let [_, _, end] = prop.att;
            self.x.fixed_rows_mut::<3>(0).copy_from(&end);
            self.accel = [z.x as f32, z.y as f32, z.z as f32];
        } // At gimbal lock the attitude stops and the last output repeats.
        self.frame.advance(&period);
        self.seq = self.seq.wrapping_add(1);
        self.t_us = self.t_us.saturating_add((self.dt * 1e6).round() as u64);
        let g = wrap_angles(&self.layout.attitude(&self.x));
        Sample {
            seq: self.seq,
            t_us: self.t_us,
            dt: self.dt as f32,
            dtheta_cmd: [dtheta.x, dtheta.y, dtheta.z],
            c_cn_quat: quaternion_from_dcm(&self.frame.c_cn).map(|v| v as f32),
            accel_mean: self.accel,
            gimbal: self
                .layout
                .gimbal_obs
                .then_some([g.x as f32, g.y as f32, g.z as f32]),
        }
    }
}

/// Perturbs a model sample (rarely).
fn perturb(u: &mut Unstructured, s: &mut Sample, p: &mut Platform) -> Result<()> {
    for _ in 0..u.int_in_range(0..=2u8)? {
        match u.int_in_range(0..=12u8)? {
            0 => s.accel_mean[usize::from(u.int_in_range(0..=2u8)?)] += 1e-4, // an outlier
            1 => {
                let i = usize::from(u.int_in_range(0..=2u8)?);
                s.accel_mean[i] = value32(u, s.accel_mean[i])?;
            }
            2 => {
                let i = usize::from(u.int_in_range(0..=2u8)?);
                s.dtheta_cmd[i] = value(u, s.dtheta_cmd[i])?;
            }
            3 => {
                let i = usize::from(u.int_in_range(0..=3u8)?);
                s.c_cn_quat[i] = value32(u, s.c_cn_quat[i])?;
            }
            4 => s.c_cn_quat = s.c_cn_quat.map(|v| -v), // the same rotation
            5 => s.dt = value32(u, s.dt)?,
            6 => s.gimbal = None,
            7 => {
                let mut g = s.gimbal.unwrap_or_default();
                let i = usize::from(u.int_in_range(0..=2u8)?);
                g[i] = value32(u, g[i])?;
                s.gimbal = Some(g);
            }
            // Timestamp jitter, or a clock step the platform keeps.
            8 => s.t_us = s.t_us.wrapping_add_signed(i64::from(u.arbitrary::<i16>()?)),
            9 => {
                let step = i64::from(u.arbitrary::<i32>()?);
                p.t_us = p.t_us.wrapping_add_signed(step);
                s.t_us = p.t_us;
            }
            10 => s.seq = s.seq.wrapping_sub(u.int_in_range(1..=3)?), // repeat / go back
            11 => s.seq = u.arbitrary()?,
            _ => s.t_us = u.arbitrary()?,
        }
    }
    Ok(())
}

fn arbitrary_sample(u: &mut Unstructured) -> Result<Sample> {
    let mut a3 = || -> Result<[f32; 3]> { Ok([u.arbitrary()?, u.arbitrary()?, u.arbitrary()?]) };
    let accel_mean = a3()?;
    let gimbal = a3()?;
    let dtheta_cmd = [u.arbitrary()?, u.arbitrary()?, u.arbitrary()?];
    Ok(Sample {
        seq: u.arbitrary()?,
        t_us: u.arbitrary()?,
        dt: u.arbitrary()?,
        dtheta_cmd,
        c_cn_quat: [
            u.arbitrary()?,
            u.arbitrary()?,
            u.arbitrary()?,
            u.arbitrary()?,
        ],
        accel_mean,
        gimbal: u.arbitrary::<bool>()?.then_some(gimbal),
    })
}

/// Corrupts a checkpoint (its dimensions, values or bookkeeping).
fn corrupt(u: &mut Unstructured, cp: &mut Checkpoint) -> Result<()> {
    match u.int_in_range(0..=9u8)? {
        0 => cp.config = pick_config(u)?,
        1 => {
            cp.state.pop();
        }
        2 => {
            let _ = cp.factor.push(1.0);
        }
        3 => {
            if let Some(v) = cp.state.iter_mut().next() {
                *v = value(u, *v)?;
            }
        }
        4 => {
            // A diagonal entry (D) of the upper triangle.
            let n = cp.state.len();
            let r = usize::from(u.arbitrary::<u8>()?) % n.max(1);
            let i = rollcal::wire::factor_index(n, r, r);
            if let Some(v) = cp.factor.get_mut(i) {
                *v = value(u, -*v)?;
            }
        }
        5 => {
            cp.nominal = if cp.nominal.is_some() {
                None
            } else {
                Some(cp.state.clone())
            }
        }
        6 => cp.c_cn[usize::from(u.int_in_range(0..=8u8)?)] = value(u, 1.0)?,
        7 => {
            cp.progress.logged = u.arbitrary()?;
            cp.progress.log_incomplete = None;
        }
        8 => {
            cp.progress.last_seq = u.arbitrary()?;
            cp.progress.last_t_us = u.arbitrary()?;
            cp.progress.clock_candidate = u.arbitrary()?;
        }
        _ => {
            let p = &mut cp.progress;
            p.accepted = u.arbitrary()?;
            p.rejects.filter = u.arbitrary()?;
            p.since_estimate = u.arbitrary()?;
            p.last_increment = [value(u, 0.0)?, value(u, 0.0)?, value(u, 0.0)?];
            cp.gated_run = u.arbitrary()?;
            cp.gate_open = u.arbitrary()?;
        }
    }
    Ok(())
}

/// The frame of `m` (must encode: `MAX_FRAME_LEN` holds every message).
fn frame(m: &Message) -> Vec<u8> {
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    let n = encode(m, &mut buf).expect("every message encodes into MAX_FRAME_LEN");
    buf.truncate(n);
    buf
}

/// `m` through the wire: the decoded message, bit-identical.
fn wire(m: &Message) -> Message {
    let bytes = frame(m);
    let mut out = Vec::new();
    let mut d = FrameDecoder::new();
    d.feed(&bytes, |x| out.push(x));
    assert_eq!(out.len(), 1, "one frame, one message");
    let m2 = out.pop().expect("one message");
    assert_eq!(frame(&m2), bytes, "decoded message re-encodes identically");
    m2
}

/// A checkpoint's bytes (NaN-safe comparison; postcard without the
/// frame's CRC and COBS, which would dominate the run time).
fn cp_bytes(c: &Checkpoint) -> CpBytes {
    CpBytes(
        postcard::to_allocvec(c).expect("checkpoint serialises"),
        c.clone(),
    )
}

/// A checkpoint compared by its bytes (NaN-safe), shown by its values (a
/// failed comparison prints what differs, not 12 KB of bytes).
struct CpBytes(Vec<u8>, Checkpoint);

impl PartialEq for CpBytes {
    fn eq(&self, other: &Self) -> bool {
        self.0 == other.0
    }
}

impl core::fmt::Debug for CpBytes {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let c = &self.1;
        let n = c.state.len();
        let diagonal: Vec<f64> = (0..n)
            .map(|i| {
                c.factor
                    .get(rollcal::wire::factor_index(n, i, i))
                    .copied()
                    .unwrap_or(f64::NAN)
            })
            .collect();
        let non_finite = c.factor.iter().filter(|v| !v.is_finite()).count();
        write!(
            f,
            "{:?}/{:?} state {:?} D {:?} ({non_finite} non-finite factor entries) c_cn {:?} updates {} gate ({}, {}) progress {:?}",
            c.config, c.errors, c.state, diagonal, c.c_cn, c.updates, c.gated_run, c.gate_open, c.progress
        )
    }
}

/// The bookkeeping's bytes (NaN-safe comparison).
fn progress_bytes(p: &Progress) -> Vec<u8> {
    postcard::to_allocvec(p).expect("progress serialises")
}

fn same_progress(a: &Progress, b: &Progress) -> bool {
    progress_bytes(a) == progress_bytes(b)
}

/// Bytes of a NOR flash sector in the model (small, so that a short run
/// crosses sectors and wraps nothing: the log's region is a few of them).
const SECTOR: usize = 512;
/// Bytes of a programmed word.
const WORD: usize = 4;
/// Sectors of the flash log's region.
const LOG_SECTORS: usize = 4;

/// A NOR flash in RAM with the semantics `FlashLog` relies on (erase to
/// `0xFF` by sector, programming only clears bits, no word programmed twice
/// between erases: both asserted, a violation is a crash), and faults the
/// input arms: the next write or erase fails having landed part of itself,
/// then the device works again (a transient error) or stays dead until the
/// harness "restores power" by reopening the log (a power cut).
#[derive(Debug)]
struct Nor {
    mem: Vec<u8>,
    /// Per word: programmed since its sector's last erase.
    written: Vec<bool>,
    /// Shared with the harness, which arms faults while the log owns the
    /// device.
    fault: Rc<Cell<Fault>>,
}

/// A fault the harness arms.
#[derive(Clone, Copy, Debug, Default)]
struct Fault {
    /// Write or erase operations until the fault (1 = the next one; 0 =
    /// none armed).
    in_ops: u16,
    /// Words of the faulted operation that land (modulo its length).
    lands: u16,
    /// The fault is a power cut: every later operation fails.
    cuts: bool,
    /// Power is off.
    dead: bool,
}

impl Nor {
    /// A device as shipped: every bit programmed, so nothing is taken for
    /// erased before the log erases it.
    fn new(fault: Rc<Cell<Fault>>) -> Self {
        Self {
            mem: vec![0; LOG_SECTORS * SECTOR],
            written: vec![true; LOG_SECTORS * SECTOR / WORD],
            fault,
        }
    }

    fn dead(&self) -> bool {
        self.fault.get().dead
    }

    /// Whether this operation (of `len` bytes) faults: `Some(bytes landed)`.
    fn fault_now(&mut self, len: usize) -> Option<usize> {
        let mut f = self.fault.get();
        match f.in_ops {
            0 => return None,
            1 => {}
            _ => {
                f.in_ops -= 1;
                self.fault.set(f);
                return None;
            }
        }
        f.in_ops = 0;
        f.dead = f.cuts;
        self.fault.set(f);
        let words = len / WORD;
        Some(usize::from(f.lands) % words.max(1) * WORD)
    }

    fn range(&self, offset: u32, len: usize, align: usize) -> Result<usize, NorFlashErrorKind> {
        let at = offset as usize;
        if at % align != 0 || len % align != 0 {
            return Err(NorFlashErrorKind::NotAligned);
        }
        if at.checked_add(len).is_none_or(|e| e > self.mem.len()) {
            return Err(NorFlashErrorKind::OutOfBounds);
        }
        Ok(at)
    }
}

impl ErrorType for Nor {
    type Error = NorFlashErrorKind;
}

impl ReadNorFlash for Nor {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> core::result::Result<(), Self::Error> {
        if self.dead() {
            return Err(NorFlashErrorKind::Other);
        }
        let at = self.range(offset, bytes.len(), 1)?;
        bytes.copy_from_slice(&self.mem[at..at + bytes.len()]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.mem.len()
    }
}

impl NorFlash for Nor {
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = SECTOR;

    fn erase(&mut self, from: u32, to: u32) -> core::result::Result<(), Self::Error> {
        if self.dead() {
            return Err(NorFlashErrorKind::Other);
        }
        let len = (to as usize)
            .checked_sub(from as usize)
            .ok_or(NorFlashErrorKind::OutOfBounds)?;
        let at = self.range(from, len, SECTOR)?;
        let landed = self.fault_now(len);
        let end = at + landed.unwrap_or(len);
        self.mem[at..end].fill(0xFF);
        self.written[at / WORD..end / WORD].fill(false);
        match landed {
            Some(_) => Err(NorFlashErrorKind::Other),
            None => Ok(()),
        }
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> core::result::Result<(), Self::Error> {
        if self.dead() {
            return Err(NorFlashErrorKind::Other);
        }
        let at = self.range(offset, bytes.len(), WORD)?;
        for w in at / WORD..(at + bytes.len()) / WORD {
            assert!(
                !self.written[w],
                "word {w} programmed twice without an erase"
            );
        }
        let landed = self.fault_now(bytes.len());
        let n = landed.unwrap_or(bytes.len());
        for (i, b) in bytes[..n].iter().enumerate() {
            assert_eq!(
                self.mem[at + i] & b,
                *b,
                "byte {} programmed from 0 to 1",
                at + i
            );
            self.mem[at + i] = *b;
        }
        self.written[at / WORD..(at + n) / WORD].fill(true);
        match landed {
            Some(_) => Err(NorFlashErrorKind::Other),
            None => Ok(()),
        }
    }
}

/// The session's sample log: a small `SliceLog` in RAM, or a `FlashLog`
/// over the NOR model (`None` when the device could not be opened: every
/// append then fails, as in the firmware).
enum Log<'a, T: RealField + Copy> {
    Ram(SliceLog<'a, T>),
    Flash(Option<FlashLog<Nor, T>>),
}

impl<T: RealField + Copy> Log<'_, T> {
    /// The flash log over `nor`, read in `layout` (what a device that lost
    /// its RAM, or one told another configuration, finds).
    fn open_flash(nor: Nor, layout: PackedLayout) -> Self {
        let region = 0..(LOG_SECTORS * SECTOR) as u32;
        Log::Flash(FlashLog::open(nor, region, layout).ok())
    }

    /// Power off and on: the device back, the log reopened from what it
    /// holds, in the layout it was read in (the firmware's start-up reads
    /// it in the layout of the gimbal angles; the harness keeps the last
    /// one, as a restore into the same configuration needs).
    fn power_cycle(&mut self) {
        if let Log::Flash(slot) = self {
            if let Some(log) = slot.take() {
                let layout = log.layout();
                let nor = log.into_inner();
                nor.fault.set(Fault::default());
                *self = Self::open_flash(nor, layout);
            }
        }
    }

    /// As the firmware does after a `Configure`: the log read in the layout
    /// of `z` measurements a period, reopened from the device if it was
    /// read in another (the records of an earlier run in that layout come
    /// back; the calibrator's first sample empties the log, a restore
    /// takes it back to the checkpoint's records).
    fn use_layout(&mut self, z: usize) {
        let layout = PackedLayout::for_measurements(z);
        if let Log::Flash(slot) = self {
            if slot.as_ref().is_some_and(|l| l.layout() != layout) {
                if let Some(log) = slot.take() {
                    *self = Self::open_flash(log.into_inner(), layout);
                }
            }
        }
    }
}

impl<T: RealField + Copy> SampleLog<T> for Log<'_, T> {
    fn append(&mut self, record: &LogRecord<T>) -> core::result::Result<(), LogError> {
        match self {
            Log::Ram(l) => l.append(record),
            Log::Flash(Some(l)) => l.append(record),
            Log::Flash(None) => Err(LogError::Storage),
        }
    }

    fn len(&self) -> usize {
        match self {
            Log::Ram(l) => l.len(),
            Log::Flash(Some(l)) => l.len(),
            Log::Flash(None) => 0,
        }
    }

    fn get(&mut self, k: usize) -> Option<LogRecord<T>> {
        match self {
            Log::Ram(l) => l.get(k),
            Log::Flash(Some(l)) => l.get(k),
            Log::Flash(None) => None,
        }
    }

    fn truncate(&mut self, len: usize) {
        match self {
            Log::Ram(l) => l.truncate(len),
            Log::Flash(Some(l)) => l.truncate(len),
            Log::Flash(None) => {}
        }
    }
}

/// What the harness knows of the calibrator's history since its progress
/// was last fresh (a `Configure` or `Reset`), carried by its checkpoints.
#[derive(Clone, Copy, Debug)]
struct Lineage {
    /// Samples pushed since.
    pushes: u32,
    /// False once restored from a corrupted checkpoint (its counters are
    /// then arbitrary).
    legit: bool,
}

impl Lineage {
    const FRESH: Self = Self {
        pushes: 0,
        legit: true,
    };
}

/// Harness tallies of what the session should have counted.
#[derive(Default, Debug, Clone, Copy)]
struct Tally {
    unconfigured: u32,
    restarts: u32,
    ignored: u32,
    errors: u32,
    finishes: u32,
}

/// The session under test, its log, and what the harness expects of them.
struct Harness<'a, T: RealField + Copy> {
    session: Session<T>,
    /// The configuration the session was told to run.
    expected: Option<ConfigId>,
    log: Log<'a, T>,
    /// The log's capacity (records; the flash log's in its larger layout).
    cap: usize,
    /// The flash device's faults, armed by the input.
    fault: Rc<Cell<Fault>>,
    /// Estimator options the session was built with.
    passes: EstimatorOptions,
    tally: Tally,
    lineage: Lineage,
    frame_errors: u32,
    checkpoints: Vec<(Checkpoint, Lineage)>,
    estimates: Vec<Estimate>,
}

fn run<T: RealField + Copy>(u: &mut Unstructured) -> Result<()> {
    let expected = if rare(u, 8) {
        Some(pick_config(u)?)
    } else {
        None
    };
    let passes = EstimatorOptions {
        max_passes: u.int_in_range(0..=4u8)?,
        tolerance: value(u, 0.1)?,
    };
    // The log: one input in two a flash log over the NOR model (read in
    // the gimbal angles' layout at start, as the firmware does), else a
    // small RAM log.
    let fault = Rc::new(Cell::new(Fault::default()));
    let flash = rare(u, 2);
    let cap = if flash {
        LOG_SECTORS * (SECTOR / FlashLog::<Nor, T>::slot_len_of(PackedLayout::Accel))
    } else if rare(u, 4) {
        usize::from(u.int_in_range(0..=LOG_CAP as u8)?)
    } else {
        LOG_CAP
    };
    let mut buf = vec![LogRecord::<T>::predicted(1.0, Vector3::zeros()); cap];
    let log = if flash {
        Log::open_flash(Nor::new(fault.clone()), PackedLayout::AccelGimbal)
    } else {
        Log::Ram(SliceLog::new(&mut buf))
    };
    let mut h = Harness {
        session: Session::<T>::new(expected, passes),
        expected,
        log,
        cap,
        fault,
        passes,
        tally: Tally::default(),
        lineage: Lineage::FRESH,
        frame_errors: 0,
        checkpoints: Vec::new(),
        estimates: Vec::new(),
    };

    let first = pick_config(u)?;
    let first_settings = settings(u, first)?;
    let mut platform = Platform::new(u, &first_settings)?;
    let mut pending = (!rare(u, 8)).then_some(Message::Configure(first_settings));

    let count = MAX_MESSAGES - usize::from(u.int_in_range(0..=MAX_MESSAGES as u8)?);
    for _ in 0..count {
        // The lineage a restored checkpoint carries.
        let mut restored = None;
        let msg = match pending.take() {
            Some(m) => m,
            None => match u.int_in_range(0..=255u8)? {
                0..=159 => {
                    // The platform's next sample, maybe after lost ones.
                    let lost = if rare(u, 8) {
                        u.int_in_range(1..=12u8)?
                    } else {
                        0
                    };
                    let mut s = platform.period();
                    for _ in 0..lost {
                        platform.steer(u)?;
                        s = platform.period();
                    }
                    platform.steer(u)?;
                    if rare(u, 4) {
                        perturb(u, &mut s, &mut platform)?;
                    }
                    Message::Sample(s)
                }
                160..=167 => Message::Sample(arbitrary_sample(u)?),
                168..=179 => Message::EstimateRequest,
                180..=189 => Message::CheckpointRequest,
                190..=197 if !h.checkpoints.is_empty() => {
                    let i = u.choose_index(h.checkpoints.len())?;
                    let (cp, l) = h.checkpoints[i].clone();
                    restored = Some(l);
                    Message::Checkpoint(cp)
                }
                198..=203 => {
                    let mut cp = match (h.checkpoints.last(), h.session.calibrator()) {
                        (Some((c, _)), _) => c.clone(),
                        (None, Some(c)) => c.checkpoint(),
                        (None, None) => {
                            AnyCalibrator::<T>::new(CalibratorConfig::paper(pick_config(u)?))
                                .expect("the paper's settings are valid")
                                .checkpoint()
                        }
                    };
                    corrupt(u, &mut cp)?;
                    restored = Some(Lineage {
                        pushes: 0,
                        legit: false,
                    });
                    Message::Checkpoint(cp)
                }
                204..=211 => {
                    if rare(u, 2) {
                        platform = Platform::new(u, &first_settings)?;
                    }
                    Message::Reset
                }
                212..=219 => Message::Finish,
                220..=227 => {
                    let id = if rare(u, 2) {
                        pick_config(u)?
                    } else {
                        h.session
                            .calibrator()
                            .map_or(first, |c| c.settings().config)
                    };
                    let s = settings(u, id)?;
                    if rare(u, 2) {
                        platform = Platform::new(u, &s)?;
                    }
                    Message::Configure(s)
                }
                228..=233 => match h.estimates.last() {
                    Some(e) => Message::Estimate(e.clone()),
                    None => continue,
                },
                234..=239 => {
                    h.frame_errors = u.arbitrary()?;
                    if let Some(c) = h.session.calibrator_mut() {
                        c.set_frame_errors(h.frame_errors);
                    }
                    continue;
                }
                240..=247 => {
                    // The log outside the calibrator's control: lost
                    // (cleared), cut short, or holding a foreign record.
                    // On flash also: a device reset (the session lost,
                    // the log reopened from the device), or a write or
                    // erase that fails part-way (then the device works
                    // again, or has lost power until the next reset).
                    match u.int_in_range(0..=4u8)? {
                        0 => h.log.truncate(0),
                        1 => h.log.truncate(usize::from(u.arbitrary::<u8>()?)),
                        3 if matches!(h.log, Log::Flash(_)) => h.power_cycle(),
                        4 if matches!(h.log, Log::Flash(_)) => h.fault.set(Fault {
                            in_ops: u.int_in_range(1..=8u16)?,
                            lands: u.arbitrary()?,
                            cuts: u.arbitrary()?,
                            dead: h.fault.get().dead,
                        }),
                        _ => {
                            let _ = h.log.append(&LogRecord::predicted(1.0, Vector3::zeros()));
                        }
                    }
                    continue;
                }
                _ => Message::Sample(platform.period()),
            },
        };
        let msg = match msg {
            Message::Finish if h.tally.finishes >= MAX_FINISH => Message::EstimateRequest,
            Message::Finish => {
                h.tally.finishes += 1;
                Message::Finish
            }
            Message::Sample(mut s) => {
                // Fold long jumps of the sequence number (see MAX_GAP).
                let last = h.session.calibrator().and_then(|c| c.progress().last_seq);
                if let Some(l) = last {
                    if s.seq > l && s.seq - l > MAX_GAP {
                        s.seq = l + 1 + (s.seq - l) % MAX_GAP;
                    }
                }
                Message::Sample(s)
            }
            m => m,
        };
        h.handle(&wire(&msg), restored);
    }
    if std::env::var_os("ROLLCAL_FUZZ_TRACE").is_some() {
        eprintln!(
            "{:?} {:?}",
            h.session.stats(),
            h.session.calibrator().map(|c| *c.progress())
        );
    }
    Ok(())
}

/// Counts of every rejection reason, in `RejectCounts` order.
fn reject_slots(p: &Progress) -> [u32; 12] {
    let c = &p.rejects;
    [
        c.non_finite,
        c.period,
        c.accel_range,
        c.increment_range,
        c.gimbal_range,
        c.missing_gimbal,
        c.duplicate,
        c.out_of_order,
        c.time_backwards,
        c.time_mismatch,
        c.frame_attitude,
        c.filter,
    ]
}

fn reject_slot(r: RejectReason) -> usize {
    match r {
        RejectReason::NonFinite => 0,
        RejectReason::Period => 1,
        RejectReason::AccelRange => 2,
        RejectReason::IncrementRange => 3,
        RejectReason::GimbalRange => 4,
        RejectReason::MissingGimbal => 5,
        RejectReason::Duplicate => 6,
        RejectReason::OutOfOrder => 7,
        RejectReason::TimeBackwards => 8,
        RejectReason::TimeMismatch => 9,
        RejectReason::FrameAttitude => 10,
        RejectReason::Filter(_) => 11,
        _ => panic!("a new reject reason: {r:?}"),
    }
}

/// Settings' bytes (NaN-safe comparison).
fn settings_bytes(s: &CalibratorConfig) -> Vec<u8> {
    postcard::to_allocvec(s).expect("settings serialise")
}

impl<T: RealField + Copy> Harness<'_, T> {
    /// A device reset: the session (RAM) lost, a new one built as at start,
    /// the flash log reopened from the device.
    fn power_cycle(&mut self) {
        self.session = Session::<T>::new(self.expected, self.passes);
        self.tally = Tally {
            finishes: self.tally.finishes,
            ..Tally::default()
        };
        self.lineage = Lineage::FRESH;
        self.frame_errors = 0;
        self.log.power_cycle();
    }

    fn handle(&mut self, msg: &Message, restored: Option<Lineage>) {
        let before = self.session.calibrator().cloned();
        // The checkpoints' bytes, formed only where compared (a full-model
        // checkpoint is 1 600 values).
        let before_cp = || before.as_ref().map(|c| cp_bytes(&c.checkpoint()));
        let log_before = self.log.len();
        let reply = self.session.handle(msg, &mut self.log);
        if let (Message::Configure(s), Reply::Nothing) = (msg, &reply) {
            self.log.use_layout(s.config.layout_with(s.errors).z());
        }
        // Every reply goes out through the wire.
        if let Reply::Send(m) = &reply {
            wire(m);
        }
        if matches!(reply, Reply::Error(_)) {
            self.tally.errors += 1;
        }
        let after = self.session.calibrator().cloned();
        let after_cp = || after.as_ref().map(|c| cp_bytes(&c.checkpoint()));
        let unchanged = || {
            assert_eq!(before_cp(), after_cp(), "{msg:?} changed the calibrator");
            if let (Some(b), Some(a)) = (&before, &after) {
                assert_eq!(settings_bytes(b.settings()), settings_bytes(a.settings()));
            }
        };
        let not_configured = || {
            assert_eq!(reply, Reply::Error(SessionError::NotConfigured), "{msg:?}");
            assert!(after.is_none());
        };

        match msg {
            Message::Configure(s) => {
                let found = s.config;
                match (self.expected, AnyCalibrator::<T>::new(*s)) {
                    (Some(e), _) if e != found => {
                        assert_eq!(
                            reply,
                            Reply::Error(SessionError::ConfigMismatch { expected: e, found })
                        );
                        unchanged();
                    }
                    (_, Err(e)) => {
                        assert_eq!(reply, Reply::Error(SessionError::Calibrator(e)));
                        unchanged();
                    }
                    (_, Ok(fresh)) => {
                        assert_eq!(reply, Reply::Nothing);
                        let a = after.as_ref().expect("configured");
                        assert_eq!(settings_bytes(a.settings()), settings_bytes(s));
                        assert_eq!(cp_bytes(&a.checkpoint()), cp_bytes(&fresh.checkpoint()));
                        assert!(same_progress(a.progress(), &Progress::default()));
                        if before.is_some() {
                            self.tally.restarts += 1;
                        }
                        self.lineage = Lineage::FRESH;
                        self.frame_errors = 0;
                    }
                }
            }
            Message::Estimate(_) | Message::Refused(_) => {
                assert_eq!(reply, Reply::Nothing);
                self.tally.ignored += 1;
                unchanged();
            }
            Message::Sample(_) if before.is_none() => {
                not_configured();
                self.tally.unconfigured += 1;
            }
            Message::Sample(s) => {
                let (b, a) = (before.as_ref().unwrap(), after.as_ref().unwrap());
                self.check_sample(b, a, s, &reply);
                self.lineage.pushes = self.lineage.pushes.saturating_add(1);
            }
            _ if before.is_none() => not_configured(),
            Message::EstimateRequest => {
                unchanged();
                let c = after.as_ref().unwrap();
                let Reply::Send(Message::Estimate(e)) = &reply else {
                    panic!("{reply:?}")
                };
                assert_eq!(e.kind, EstimateKind::Running);
                self.check_estimate(c, e);
            }
            Message::CheckpointRequest => {
                unchanged();
                let c = after.as_ref().unwrap();
                let Reply::Send(Message::Checkpoint(cp)) = &reply else {
                    panic!("{reply:?}")
                };
                let n = c.settings().config.layout_with(c.settings().errors).n();
                assert_eq!(
                    (cp.config, cp.errors),
                    (c.settings().config, c.settings().errors)
                );
                assert_eq!(
                    (cp.state.len(), cp.factor.len()),
                    (n, rollcal::wire::factor_len(n))
                );
                assert!(same_progress(&cp.progress, c.progress()));
                // Its own checkpoint restores, bit-identically — except
                // once the factor has a negative D (the
                // factored filter refuses any update that would leave one,
                // so this should not happen), which `Filter::from_parts`
                // refuses. A zero D is a state the model does not estimate
                // (its prior σ zero): restored like any other.
                let degenerate =
                    (0..n).any(|i| cp.factor[rollcal::wire::factor_index(n, i, i)] < 0.0);
                let mut again = c.clone();
                let restored = again.restore(cp);
                if degenerate {
                    assert_eq!(
                        restored,
                        Err(rollcal::calibrator::Error::Filter(
                            rollcal::Error::CovarianceNotPositiveDefinite
                        ))
                    );
                } else {
                    if let Err(e) = restored {
                        panic!(
                            "a calibrator's own checkpoint refused: {e}; {:?}",
                            cp_bytes(cp)
                        );
                    }
                    assert_eq!(cp_bytes(&again.checkpoint()), cp_bytes(cp));
                }
                if self.checkpoints.len() >= 8 {
                    self.checkpoints.remove(0);
                }
                self.checkpoints.push((cp.clone(), self.lineage));
            }
            Message::Checkpoint(cp) => {
                let mut expect = before.clone().unwrap();
                match expect.restore(cp) {
                    Ok(()) => {
                        assert_eq!(reply, Reply::Nothing);
                        let a = after.as_ref().unwrap();
                        assert_eq!(after_cp(), Some(cp_bytes(&expect.checkpoint())));
                        let lineage = restored.unwrap_or(Lineage {
                            pushes: 0,
                            legit: false,
                        });
                        // f64 values round-trip through an f64 filter, and
                        // an f32 filter's own values through an f32 one.
                        if core::mem::size_of::<T>() == 8 || lineage.legit {
                            assert_eq!(cp_bytes(&a.checkpoint()), cp_bytes(cp));
                        }
                        assert_eq!(
                            settings_bytes(a.settings()),
                            settings_bytes(before.as_ref().unwrap().settings())
                        );
                        self.lineage = lineage;
                        self.frame_errors = 0;
                    }
                    Err(e) => {
                        assert_eq!(reply, Reply::Error(SessionError::Calibrator(e)));
                        unchanged();
                    }
                }
            }
            Message::Reset => {
                assert_eq!(reply, Reply::Nothing);
                let a = after.as_ref().unwrap();
                assert!(same_progress(a.progress(), &Progress::default()));
                let fresh = AnyCalibrator::<T>::new(*a.settings()).expect("valid settings");
                assert_eq!(cp_bytes(&a.checkpoint()), cp_bytes(&fresh.checkpoint()));
                self.tally.restarts += 1;
                self.lineage = Lineage::FRESH;
            }
            Message::Finish => {
                unchanged();
                let c = after.as_ref().unwrap();
                let p = c.progress();
                let Reply::Send(Message::Estimate(e)) = &reply else {
                    panic!("{reply:?}")
                };
                self.check_estimate(c, e);
                assert!(self.log.len() <= log_before);
                match (p.log_incomplete, e.kind) {
                    (Some(r), kind) => assert_eq!(
                        kind,
                        EstimateKind::SinglePass {
                            reason: r,
                            logged: p.logged
                        }
                    ),
                    (None, EstimateKind::Final { passes, .. }) => {
                        let max = self.session.passes().max_passes.max(1);
                        assert!((1..=max).contains(&passes), "{passes} passes");
                        assert_eq!(self.log.len(), p.logged as usize);
                    }
                    (None, EstimateKind::SinglePass { reason, logged }) => {
                        assert_eq!(logged, p.logged);
                        match reason {
                            SinglePassReason::LogMismatch => {
                                assert_ne!(self.log.len(), p.logged as usize)
                            }
                            SinglePassReason::Estimator => {
                                assert_eq!(self.log.len(), p.logged as usize)
                            }
                            r => panic!("single pass for {r:?} with a complete log"),
                        }
                    }
                    (None, EstimateKind::Running) => panic!("Finish answered a running estimate"),
                }
            }
        }
        if let Reply::Send(Message::Estimate(e)) = &reply {
            if self.estimates.len() >= 4 {
                self.estimates.remove(0);
            }
            self.estimates.push(e.clone());
        }
        self.check_session();
        self.check_lineage();
    }

    /// An estimate of calibrator `c`: its configuration, bookkeeping and
    /// the frame-error count the harness gave it.
    fn check_estimate(&self, c: &AnyCalibrator<T>, e: &Estimate) {
        let n = c.settings().config.layout_with(c.settings().errors).n();
        assert_eq!(
            (e.config, e.errors),
            (c.settings().config, c.settings().errors)
        );
        assert_eq!((e.state.len(), e.sigma.len()), (n, n));
        assert!(same_progress(&e.progress, c.progress()));
        assert_eq!(e.seq, c.progress().last_seq.unwrap_or(0));
        assert_eq!(e.frame_errors, self.frame_errors);
    }

    /// One sample's effect on the bookkeeping.
    fn check_sample(&self, b: &AnyCalibrator<T>, a: &AnyCalibrator<T>, s: &Sample, reply: &Reply) {
        let (pb, pa) = (b.progress(), a.progress());
        assert_eq!(settings_bytes(b.settings()), settings_bytes(a.settings()));
        let inc = |x: u32| x.saturating_add(1);
        // The first reason stays.
        if pb.log_incomplete.is_some() {
            assert_eq!(pa.log_incomplete, pb.log_incomplete);
        }
        assert!(pa.logged >= pb.logged);
        assert!(pa.reacquired == pb.reacquired || pa.reacquired == inc(pb.reacquired));
        assert!(pa.clock_steps == pb.clock_steps || pa.clock_steps == inc(pb.clock_steps));
        let bridged = pa.bridged - pb.bridged;
        let reacquired = pa.reacquired - pb.reacquired;
        assert!(bridged == 0 || reacquired == 0, "bridged and re-acquired");
        if reacquired > 0 {
            assert!(pa.log_incomplete.is_some());
            assert!(
                pa.reacquired_periods > pb.reacquired_periods || pb.reacquired_periods == u32::MAX
            );
        }
        // A gap is at most MAX_GAP - 1 periods (the harness folds longer jumps).
        assert!(bridged < MAX_GAP);
        match reply {
            Reply::Nothing | Reply::Send(Message::Estimate(_)) => {
                assert_eq!(pa.accepted, inc(pb.accepted));
                assert_eq!(reject_slots(pa), reject_slots(pb));
                assert!(pa.gated == pb.gated || pa.gated == inc(pb.gated));
                assert_eq!((pa.last_seq, pa.last_t_us), (Some(s.seq), Some(s.t_us)));
                assert_eq!(pa.clock_candidate, None);
                let every = a.settings().estimate_every;
                if every > 0 {
                    assert!(pa.since_estimate < every);
                }
                let emitted = matches!(reply, Reply::Send(_));
                assert_eq!(emitted, every > 0 && pa.since_estimate == 0);
                if let Reply::Send(Message::Estimate(e)) = reply {
                    assert_eq!(e.kind, EstimateKind::Running);
                    self.check_estimate(a, e);
                }
                // Its own record, and the bridged periods', while the log holds the run.
                if pa.log_incomplete.is_none() && pb.logged < u32::MAX - MAX_GAP {
                    assert_eq!(pa.logged - pb.logged, bridged + 1);
                }
            }
            Reply::Rejected(r) => {
                let i = reject_slot(*r);
                let (mut want, got) = (reject_slots(pb), reject_slots(pa));
                want[i] = inc(want[i]);
                assert_eq!(got, want, "{r:?} counted once");
                assert_eq!((pa.accepted, pa.gated), (pb.accepted, pb.gated));
                if matches!(r, RejectReason::TimeMismatch | RejectReason::TimeBackwards) {
                    assert_eq!(pa.clock_candidate, Some((s.seq, s.t_us)));
                }
                // Only bridged periods (consumed whatever the sample's own
                // period does) and their records change anything else,
                // while the log holds the run (a bridged gap that failed
                // after logging some periods marks it incomplete: with
                // `FilterFailed`, or with the reason it already had, e.g.
                // `LogFull` when it filled up inside that gap).
                if pa.log_incomplete.is_none() && pb.logged < u32::MAX - MAX_GAP {
                    assert!(
                        pa.logged - pb.logged <= bridged,
                        "{r:?}: logged {} -> {}, bridged {bridged}; before {pb:?}; after {pa:?}",
                        pb.logged,
                        pa.logged
                    );
                }
                if bridged == 0 && reacquired == 0 {
                    // The filter (and everything but the rejection's own
                    // bookkeeping) is untouched; the log may have been found
                    // shorter than the calibrator's count before validation.
                    let mut cp = a.checkpoint();
                    let p = &mut cp.progress;
                    p.rejects = pb.rejects;
                    p.clock_candidate = pb.clock_candidate;
                    if pb.log_incomplete.is_none()
                        && p.log_incomplete == Some(SinglePassReason::LogMismatch)
                    {
                        p.log_incomplete = None;
                    }
                    // A gap whose prediction the filter refused part-way:
                    // the filter is restored, the records already logged
                    // are marked (FilterFailed, or the reason the log got
                    // inside that gap: LogFull when it filled up there).
                    if pb.log_incomplete.is_none() && p.log_incomplete.is_some() {
                        p.log_incomplete = None;
                        p.logged = pb.logged;
                    }
                    assert_eq!(
                        cp_bytes(&cp),
                        cp_bytes(&b.checkpoint()),
                        "{r:?} changed the calibrator; settings {:?}",
                        b.settings()
                    );
                }
            }
            other => panic!("a sample answered {other:?}"),
        }
        if pa.log_incomplete.is_none() {
            assert_eq!(self.log.len(), pa.logged as usize);
        }
    }

    fn check_session(&self) {
        let s = self.session.stats();
        let t = &self.tally;
        assert_eq!(
            (s.unconfigured, s.restarts, s.ignored, s.errors),
            (t.unconfigured, t.restarts, t.ignored, t.errors),
            "session counters"
        );
    }

    /// Identities of a calibrator's bookkeeping that hold by construction
    /// since it was fresh (not after a corrupted checkpoint).
    fn check_lineage(&self) {
        let Some(c) = self.session.calibrator() else {
            return;
        };
        if !self.lineage.legit {
            return;
        }
        let p = c.progress();
        let r = &p.rejects;
        assert_eq!(p.accepted + r.total(), self.lineage.pushes, "{p:?}");
        assert!(p.gated <= p.accepted && p.since_estimate <= p.accepted);
        if p.log_incomplete.is_none() {
            assert_eq!(p.logged, p.accepted + p.bridged, "{p:?}");
        }
        assert!(p.logged as usize <= self.cap);
        assert!(p.reacquired <= p.reacquired_periods);
        if p.reacquired > 0 {
            assert!(p.log_incomplete.is_some());
        }
        assert!(p.clock_steps <= r.time_mismatch + r.time_backwards, "{p:?}");
        assert_eq!(p.accepted > 0, p.last_seq.is_some());
        assert_eq!(p.last_seq.is_some(), p.last_t_us.is_some());
    }
}
