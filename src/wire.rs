//! The serial wire protocol (docs/wire.md): messages, framing, and a streaming
//! decoder. The byte layout is specified in `docs/wire.md`.
//!
//! A **frame** on the wire is
//!
//! ```text
//! COBS( version:u8 | postcard(Message) | crc32:u32 little-endian ) | 0x00
//! ```
//!
//! - `version` is [`VERSION`]; a frame of another version is counted and
//!   skipped (its CRC is checked first, so a corrupt frame is never counted
//!   as a wrong version);
//! - the message is serialised with `postcard` (varint integers, `f32`/`f64`
//!   little-endian IEEE 754, enum tags as varints in declaration order);
//! - the CRC is CRC-32/ISO-HDLC (the zlib/Ethernet CRC; check value
//!   `0xCBF43926` over `"123456789"`) over the version byte and the postcard
//!   bytes;
//! - COBS removes every `0x00` from the frame, so `0x00` is the delimiter
//!   and a receiver resynchronises at the next one.
//!
//! [`encode`] writes a frame into a caller's buffer; [`Decoder`] accepts
//! bytes in chunks of any size, yields messages and counts rejected frames
//! by reason ([`DecoderStats`]). Neither allocates nor panics.
//!
//! Units and frames of every field are those of the crate (docs/model.md §Notation):
//! radians, seconds, specific force in g, navigation frame North–Up–East.

use heapless::Vec;
use serde::{Deserialize, Serialize};

use crate::ekf::Options;
use crate::models::ConfigId;

/// Protocol version carried in the first byte of every frame.
pub const VERSION: u8 = 4;

/// Largest state dimension of any configuration (M2-ps, M3-ps).
pub const MAX_STATES: usize = 18;

/// Capacity of a row-major covariance of [`MAX_STATES`] states.
pub const MAX_COVARIANCE: usize = MAX_STATES * MAX_STATES;

/// Length of the CRC trailer (bytes).
pub const CRC_LEN: usize = 4;

/// Smallest valid decoded frame: version, one tag byte, CRC (bytes).
pub const MIN_DECODED_LEN: usize = 1 + 1 + CRC_LEN;

/// Upper bound of an encoded frame of any [`Message`], delimiter included
/// (bytes). The largest message is an 18-state [`Checkpoint`] (about 3.2 KB
/// encoded); a [`Decoder`] with this capacity accepts every message.
pub const MAX_FRAME_LEN: usize = 4096;

/// Recommended decoder capacity: [`MAX_FRAME_LEN`].
pub type FrameDecoder = Decoder<MAX_FRAME_LEN>;

/// One filter period as measured by the platform (docs/wire.md). `f32` fields:
/// f32 spacing is 1.2e-7 g at 1 g (the accelerometer noise is 1e-6 g) and
/// 0.05″ at π rad (the gimbal noise is 10″).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Sequence number, +1 per period (the first sample may start anywhere).
    pub seq: u32,
    /// Time at the end of the period (µs, any fixed origin). An integer:
    /// f32 seconds would resolve only 0.5 ms after 1.5 h.
    pub t_us: u64,
    /// Period length `T` (s).
    pub dt: f32,
    /// Commanded angle increment `Δθc = ∫ωc dt` over the period (rad, c
    /// frame). `f64`: its rounding is not noise but a bias that lasts a
    /// whole path segment (the Earth rate's share of an increment is
    /// ~4e-8 rad and changes slowly): in `f32` it moved the M1-pa answer by
    /// 0.11σ.
    pub dtheta_cmd: [f64; 3],
    /// The computed frame at the end of the period, `C^c_n(t_k)`, as the unit
    /// quaternion `[w, x, y, z]` of its rotation vector θ (`C^c_n = R(θ)`,
    /// [`crate::geometry::quaternion_from_dcm`]). It makes the commanded
    /// motion across lost samples known (see [`crate::calibrator`], "Lost
    /// data"); f32 resolves it to 6e-8 rad (0.012″).
    pub c_cn_quat: [f32; 4],
    /// Mean accelerometer output over the period (g, instrument axes).
    pub accel_mean: [f32; 3],
    /// Gimbal angles `(α, β, γ)` at the end of the period (rad); required by
    /// M2-ps, ignored by the other configurations.
    pub gimbal: Option<[f32; 3]>,
}

/// Validation limits of the calibrator (see [`crate::calibrator`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Limits {
    /// Expected period `T` (s).
    pub period_s: f64,
    /// Accepted deviation of `dt` from `period_s`, and of the timestamp
    /// difference from `dt` per elapsed period (s).
    pub period_tolerance_s: f64,
    /// Largest accepted |component| of the mean specific force (g).
    pub max_accel_g: f64,
    /// Largest accepted |component| of the commanded increment (rad).
    pub max_increment_rad: f64,
    /// Largest accepted |gimbal angle| (rad).
    pub max_gimbal_rad: f64,
    /// Longest gap (missing periods) across which the calibrator searches
    /// for the commanded motion (the last path rate, then one switch to the
    /// new sample's path rate at any period boundary of the gap). A longer
    /// gap, or one whose motion is not found, re-acquires the attitude.
    pub max_bridge: u32,
    /// The motion across a gap is accepted as found when it carries the
    /// computed frame to the sample's reported `C^c_n` within this angle
    /// (rad); also the accepted norm error of the reported quaternion.
    pub frame_tolerance_rad: f64,
}

impl Default for Limits {
    /// 1 s period ± 1 ms, |f| ≤ 2 g, |Δθc| ≤ 0.1 rad, |θA| ≤ 2π, the motion
    /// across gaps of up to 7200 periods searched, frame tolerance 1e-5 rad
    /// (2″).
    fn default() -> Self {
        Self {
            period_s: 1.0,
            period_tolerance_s: 1e-3,
            max_accel_g: 2.0,
            max_increment_rad: 0.1,
            max_gimbal_rad: 2.0 * core::f64::consts::PI,
            max_bridge: 7200,
            frame_tolerance_rad: 1e-5,
        }
    }
}

/// Everything a calibrator needs to start: configuration, noise levels,
/// environment, prior, validation limits and estimate cadence. Sent as the
/// `Configure` control message; all scalars `f64` so one message serves the
/// f32 and f64 builds.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CalibratorConfig {
    /// Which estimator to run.
    pub config: ConfigId,
    /// Accelerometer noise of the period mean, 1σ per axis (g).
    pub sigma_accel_g: f64,
    /// Gyro white rate noise, 1σ per axis (rad/s).
    pub sigma_gyro_rad_s: f64,
    /// Gimbal-angle noise, 1σ per angle (rad).
    pub sigma_gimbal_rad: f64,
    /// Earth rate `ω^n_ie` (rad/s, North–Up–East).
    pub earth_rate_n: [f64; 3],
    /// Specific force at rest `f^n` (g, North–Up–East), normally `[0, 1, 0]`.
    pub gravity_n: [f64; 3],
    /// Prior σ of every state (rad); the initial estimate is zero.
    pub prior_sigma_rad: f64,
    /// Filter options (cold-start remedy, gate).
    pub options: Options,
    /// Validation limits.
    pub limits: Limits,
    /// Emit an [`Estimate`] every this many accepted samples (0 = never;
    /// [`crate::calibrator::Calibrator::estimate`] is always available).
    pub estimate_every: u32,
}

impl CalibratorConfig {
    /// The paper's settings (docs/model.md §The paper's scenario) for configuration `config`: noise
    /// 1e-6 g, 0.1°/h, 10″; latitude 34.25° with Earth rate; prior 1°;
    /// default options and limits; an estimate every 60 samples.
    pub fn paper(config: ConfigId) -> Self {
        let deg = core::f64::consts::PI / 180.0;
        let e = crate::geometry::earth_rate_n(crate::geometry::EARTH_RATE, 34.25 * deg);
        Self {
            config,
            sigma_accel_g: 1e-6,
            sigma_gyro_rad_s: 0.1 * deg / 3600.0,
            sigma_gimbal_rad: 10.0 * deg / 3600.0,
            earth_rate_n: [e.x, e.y, e.z],
            gravity_n: [0.0, 1.0, 0.0],
            prior_sigma_rad: deg,
            options: Options::default(),
            limits: Limits::default(),
            estimate_every: 60,
        }
    }
}

/// Counts of rejected samples by reason (see
/// [`crate::calibrator::RejectReason`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RejectCounts {
    /// A field is NaN or infinite.
    pub non_finite: u32,
    /// `dt` outside the expected period ± tolerance.
    pub period: u32,
    /// |specific force| component above the limit.
    pub accel_range: u32,
    /// |commanded increment| component above the limit.
    pub increment_range: u32,
    /// |gimbal angle| above the limit.
    pub gimbal_range: u32,
    /// No gimbal angles for a configuration that observes them.
    pub missing_gimbal: u32,
    /// Same sequence number as the last accepted sample.
    pub duplicate: u32,
    /// Sequence number below the last accepted one.
    pub out_of_order: u32,
    /// Timestamp not after the last accepted one.
    pub time_backwards: u32,
    /// Timestamp difference disagrees with `dt` × elapsed periods (a clock
    /// step is re-anchored once the next sample confirms it).
    pub time_mismatch: u32,
    /// The computed-frame quaternion is not a unit quaternion.
    pub frame_attitude: u32,
    /// The filter refused the period (state left untouched).
    pub filter: u32,
}

impl RejectCounts {
    /// Total of all reasons.
    pub fn total(&self) -> u32 {
        [
            self.non_finite,
            self.period,
            self.accel_range,
            self.increment_range,
            self.gimbal_range,
            self.missing_gimbal,
            self.duplicate,
            self.out_of_order,
            self.time_backwards,
            self.time_mismatch,
            self.frame_attitude,
            self.filter,
        ]
        .iter()
        .fold(0u32, |a, b| a.saturating_add(*b))
    }
}

/// Calibrator bookkeeping (part of [`Checkpoint`] and [`Estimate`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Progress {
    /// Sequence number of the last accepted sample.
    pub last_seq: Option<u32>,
    /// Timestamp of the last accepted sample (µs).
    pub last_t_us: Option<u64>,
    /// Commanded increment of the last accepted sample (rad, c frame), for
    /// finding the motion across a gap.
    pub last_increment: [f64; 3],
    /// A sample whose timestamp disagreed with the last accepted one:
    /// `(seq, t_us)`. If the next sample's timestamp agrees with it, the
    /// clock stepped and the time is re-anchored there.
    pub clock_candidate: Option<(u32, u64)>,
    /// NIS of the last update (NaN before the first).
    pub last_nis: f64,
    /// Samples accepted.
    pub accepted: u32,
    /// Missing periods bridged by prediction without measurement, along the
    /// commanded motion found across the gap.
    pub bridged: u32,
    /// Gaps across which the motion was not found: the computed frame was
    /// set from the reported `C^c_n` and the attitude states re-acquired
    /// (their covariance re-opened to the prior, the parameters' kept).
    pub reacquired: u32,
    /// Missing periods of those gaps (predicted along the shortest rotation).
    pub reacquired_periods: u32,
    /// Clock steps re-anchored.
    pub clock_steps: u32,
    /// Records appended to the sample log (measured samples and bridged
    /// periods), for the final passes.
    pub logged: u32,
    /// Why the log no longer holds the whole run (then [`Message::Finish`]
    /// can only answer with pass 1); `None` while it does.
    pub log_incomplete: Option<SinglePassReason>,
    /// Accepted samples whose update failed the NIS gate (predicted only).
    pub gated: u32,
    /// Accepted samples since the last emitted estimate.
    pub since_estimate: u32,
    /// Rejected samples by reason.
    pub rejects: RejectCounts,
}

impl Default for Progress {
    fn default() -> Self {
        Self {
            last_seq: None,
            last_t_us: None,
            last_increment: [0.0; 3],
            clock_candidate: None,
            last_nis: f64::NAN,
            accepted: 0,
            bridged: 0,
            reacquired: 0,
            reacquired_periods: 0,
            clock_steps: 0,
            logged: 0,
            log_incomplete: None,
            gated: 0,
            since_estimate: 0,
            rejects: RejectCounts::default(),
        }
    }
}

/// Why a final answer is pass 1 only, not the estimator of record over the
/// whole run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SinglePassReason {
    /// The calibrator was fed without a sample log.
    NoLog,
    /// The sample log filled up.
    LogFull,
    /// The sample log's storage failed.
    LogStorage,
    /// The log holds a different number of records than the calibrator
    /// appended (e.g. after a restore without the matching log).
    LogMismatch,
    /// A gap's motion was not found and the attitude was re-acquired: the
    /// later passes cannot yet linearise across it.
    Reacquired,
    /// A period whose gap had been bridged was then refused by the filter.
    FilterFailed,
    /// The multi-pass estimator refused the log (an empty log, or the
    /// back-propagation hit gimbal lock).
    Estimator,
    /// The sample log could not encode a record (e.g. a
    /// [`crate::estimator::PackedLog`] whose command table is full).
    LogUnrepresentable,
}

impl core::fmt::Display for SinglePassReason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            SinglePassReason::NoLog => "no sample log",
            SinglePassReason::LogFull => "the sample log is full",
            SinglePassReason::LogStorage => "the sample log's storage failed",
            SinglePassReason::LogMismatch => "the sample log does not match the calibrator",
            SinglePassReason::Reacquired => "the attitude was re-acquired after a gap",
            SinglePassReason::FilterFailed => "the filter refused a period after a bridged gap",
            SinglePassReason::Estimator => "the multi-pass estimator refused the log",
            SinglePassReason::LogUnrepresentable => "the sample log could not encode a record",
        })
    }
}

/// What an [`Estimate`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EstimateKind {
    /// The running estimate of pass 1, while samples arrive.
    Running,
    /// The answer of record: the multi-pass estimator over the whole logged
    /// run, after `passes` passes (`converged`: the last moved < 0.1σ).
    Final {
        /// Passes run.
        passes: u8,
        /// The last pass moved no state by more than the tolerance.
        converged: bool,
    },
    /// The final answer, but pass 1 only (the running estimate at the end of
    /// the stream), because of `reason`; `logged` records were in the log.
    SinglePass {
        /// Why the later passes could not run.
        reason: SinglePassReason,
        /// Records in the log.
        logged: u32,
    },
}

/// The running estimate (docs/wire.md). `f64` even from an f32 build (exact), so
/// that an f64 firmware build can be compared with the host to 1e-9 rad.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    /// The configuration; the states are in its order ([`ConfigId::states`]).
    pub config: ConfigId,
    /// Sequence number of the last accepted sample (0 before any).
    pub seq: u32,
    /// Filter updates processed.
    pub updates: u32,
    /// Estimated states (rad).
    pub state: Vec<f64, MAX_STATES>,
    /// Their σ, `√P_ii` (rad).
    pub sigma: Vec<f64, MAX_STATES>,
    /// Calibrator bookkeeping: last NIS, accepted, bridged, re-acquired,
    /// rejected by reason.
    pub progress: Progress,
    /// Frames the receiver's decoder rejected so far (as told to the
    /// calibrator by [`crate::calibrator::Calibrator::set_frame_errors`]).
    pub frame_errors: u32,
    /// A running estimate, or the final answer (and how it was reached).
    pub kind: EstimateKind,
}

/// Everything a calibrator needs to continue bit-identically after a reset.
/// Scalars are `f64` (an f32 value round-trips exactly).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint {
    /// The configuration.
    pub config: ConfigId,
    /// State `x` (rad).
    pub state: Vec<f64, MAX_STATES>,
    /// The packed U-D factor of the covariance `P = U D Uᵀ` (rad²),
    /// row-major N×N: `D` on the diagonal, the unit upper triangular `U`'s
    /// strict upper triangle above it, zeros below
    /// ([`crate::ekf::Filter::factor`]).
    pub factor: Vec<f64, MAX_COVARIANCE>,
    /// Nominal state of a linearised filter (rad), if any.
    pub nominal: Option<Vec<f64, MAX_STATES>>,
    /// `C^c_n` of the computed frame, row-major.
    pub c_cn: [f64; 9],
    /// Filter updates processed.
    pub updates: u32,
    /// Consecutive updates refused by the NIS gate just before the
    /// checkpoint ([`crate::ekf::Filter::gate_state`]).
    pub gated_run: u32,
    /// The NIS gate is held open (the last accepted update was above it).
    pub gate_open: bool,
    /// Calibrator bookkeeping.
    pub progress: Progress,
}

/// Every message of the protocol. The postcard tag is the variant's index
/// (a varint): `Sample` 0, `Estimate` 1, `Checkpoint` 2, `Configure` 3,
/// `Reset` 4, `CheckpointRequest` 5, `EstimateRequest` 6, `Finish` 7. New variants are
/// only ever appended.
// A large variant is the price of no heap (a Checkpoint is ~3 KB).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Message {
    /// Platform → calibrator: one period's measurement.
    Sample(Sample),
    /// Calibrator → host: the running estimate.
    Estimate(Estimate),
    /// Calibrator → host: a checkpoint; host → calibrator: restore from it.
    Checkpoint(Checkpoint),
    /// Host → calibrator: (re)configure and restart from the prior.
    Configure(CalibratorConfig),
    /// Host → calibrator: restart from the prior with the current settings.
    Reset,
    /// Host → calibrator: reply with a `Checkpoint`.
    CheckpointRequest,
    /// Host → calibrator: reply with an `Estimate` now.
    EstimateRequest,
    /// Host → calibrator: the run is over; run the final passes over the
    /// sample log and reply with the final `Estimate`.
    Finish,
}

// ---------------------------------------------------------------- CRC-32

const CRC_POLY_REFLECTED: u32 = 0xEDB8_8320;

const CRC_TABLE: [u32; 256] = {
    let mut t = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 {
                CRC_POLY_REFLECTED ^ (c >> 1)
            } else {
                c >> 1
            };
            k += 1;
        }
        #[allow(clippy::indexing_slicing)] // i < 256 by the loop condition (const context)
        {
            t[i] = c;
        }
        i += 1;
    }
    t
};

/// Running CRC-32/ISO-HDLC register (init and final XOR `0xFFFFFFFF`,
/// reflected, polynomial `0x04C11DB7`).
#[derive(Clone, Copy, Debug)]
struct Crc(u32);

impl Crc {
    const fn new() -> Self {
        Self(0xFFFF_FFFF)
    }
    fn update(&mut self, byte: u8) {
        let idx = usize::from((self.0 as u8) ^ byte);
        let t = match CRC_TABLE.get(idx) {
            Some(v) => *v,
            None => 0, // unreachable: idx < 256
        };
        self.0 = t ^ (self.0 >> 8);
    }
    const fn finish(self) -> u32 {
        !self.0
    }
}

/// CRC-32/ISO-HDLC of `data` (check value `crc32(b"123456789") ==
/// 0xCBF43926`), as used in the frame trailer.
pub fn crc32(data: &[u8]) -> u32 {
    let mut c = Crc::new();
    for b in data {
        c.update(*b);
    }
    c.finish()
}

// ---------------------------------------------------------------- encoder

/// Errors of [`encode`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum EncodeError {
    /// The output buffer cannot hold the frame ([`MAX_FRAME_LEN`] always can).
    BufferTooSmall,
    /// The message cannot be serialised (a vector longer than its capacity
    /// cannot be built, so this is not expected).
    Serialize,
}

impl core::fmt::Display for EncodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            EncodeError::BufferTooSmall => "output buffer too small for the frame",
            EncodeError::Serialize => "message cannot be serialised",
        })
    }
}

impl core::error::Error for EncodeError {}

/// A postcard flavor that CRCs and COBS-encodes on the fly into a slice.
struct FrameWriter<'a> {
    out: &'a mut [u8],
    /// Index of the current COBS block's code byte.
    code_idx: usize,
    /// Next write position.
    pos: usize,
    /// Current block code (1 + data bytes so far).
    code: u8,
    crc: Crc,
    overflow: bool,
}

impl<'a> FrameWriter<'a> {
    fn new(out: &'a mut [u8]) -> Self {
        let mut w = Self {
            out,
            code_idx: 0,
            pos: 1,
            code: 1,
            crc: Crc::new(),
            overflow: false,
        };
        w.push(VERSION);
        w
    }

    fn put(&mut self, idx: usize, b: u8) {
        match self.out.get_mut(idx) {
            Some(slot) => *slot = b,
            None => self.overflow = true,
        }
    }

    fn cobs_push(&mut self, b: u8) {
        if b == 0 {
            self.put(self.code_idx, self.code);
            self.code_idx = self.pos;
            self.pos = self.pos.saturating_add(1);
            self.code = 1;
        } else {
            self.put(self.pos, b);
            self.pos = self.pos.saturating_add(1);
            self.code = self.code.saturating_add(1);
            if self.code == 0xFF {
                self.put(self.code_idx, self.code);
                self.code_idx = self.pos;
                self.pos = self.pos.saturating_add(1);
                self.code = 1;
            }
        }
    }

    fn push(&mut self, b: u8) {
        self.crc.update(b);
        self.cobs_push(b);
    }
}

impl postcard::ser_flavors::Flavor for FrameWriter<'_> {
    type Output = usize;

    fn try_push(&mut self, data: u8) -> postcard::Result<()> {
        self.push(data);
        if self.overflow {
            Err(postcard::Error::SerializeBufferFull)
        } else {
            Ok(())
        }
    }

    fn finalize(mut self) -> postcard::Result<usize> {
        for b in self.crc.finish().to_le_bytes() {
            self.cobs_push(b);
        }
        self.put(self.code_idx, self.code);
        self.put(self.pos, 0);
        if self.overflow {
            return Err(postcard::Error::SerializeBufferFull);
        }
        Ok(self.pos.saturating_add(1))
    }
}

/// Encodes `msg` as one frame (delimiter included) into `out`; returns the
/// number of bytes written. A buffer of [`MAX_FRAME_LEN`] bytes always
/// suffices.
pub fn encode(msg: &Message, out: &mut [u8]) -> Result<usize, EncodeError> {
    if out.is_empty() {
        return Err(EncodeError::BufferTooSmall);
    }
    postcard::serialize_with_flavor(msg, FrameWriter::new(out)).map_err(|e| match e {
        postcard::Error::SerializeBufferFull => EncodeError::BufferTooSmall,
        _ => EncodeError::Serialize,
    })
}

// ---------------------------------------------------------------- decoder

/// Why a frame was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FrameError {
    /// The CRC does not match (bit errors, or two frames merged by a lost
    /// delimiter).
    Corrupt,
    /// The CRC matches but the bytes are not a valid message (unknown tag,
    /// bad varint, too-long vector, trailing bytes): a sender bug.
    Malformed,
    /// The frame ended early: a COBS block runs past the delimiter, or the
    /// frame is shorter than [`MIN_DECODED_LEN`] (a frame cut short, or the
    /// partial frame at the start of a stream).
    Truncated,
    /// More bytes than the decoder's capacity arrived before a delimiter.
    Oversized,
    /// A valid frame of another protocol version (the version it carries).
    WrongVersion(u8),
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FrameError::Corrupt => f.write_str("frame CRC mismatch"),
            FrameError::Malformed => f.write_str("frame is not a valid message"),
            FrameError::Truncated => f.write_str("frame truncated"),
            FrameError::Oversized => f.write_str("frame larger than the decoder buffer"),
            FrameError::WrongVersion(v) => {
                write!(f, "frame of protocol version {v} (expected {VERSION})")
            }
        }
    }
}

impl core::error::Error for FrameError {}

/// Frame counters of a [`Decoder`], by outcome.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DecoderStats {
    /// Frames decoded into a message.
    pub ok: u32,
    /// [`FrameError::Corrupt`] frames.
    pub corrupt: u32,
    /// [`FrameError::Malformed`] frames.
    pub malformed: u32,
    /// [`FrameError::Truncated`] frames.
    pub truncated: u32,
    /// [`FrameError::Oversized`] frames.
    pub oversized: u32,
    /// [`FrameError::WrongVersion`] frames.
    pub wrong_version: u32,
    /// Empty frames (two delimiters in a row): ignored, not an error.
    pub empty: u32,
}

impl DecoderStats {
    /// All rejected frames.
    pub fn errors(&self) -> u32 {
        [
            self.corrupt,
            self.malformed,
            self.truncated,
            self.oversized,
            self.wrong_version,
        ]
        .iter()
        .fold(0u32, |a, b| a.saturating_add(*b))
    }

    fn count<R>(&mut self, r: &Result<R, FrameError>) {
        let c = match r {
            Ok(_) => &mut self.ok,
            Err(FrameError::Corrupt) => &mut self.corrupt,
            Err(FrameError::Malformed) => &mut self.malformed,
            Err(FrameError::Truncated) => &mut self.truncated,
            Err(FrameError::Oversized) => &mut self.oversized,
            Err(FrameError::WrongVersion(_)) => &mut self.wrong_version,
        };
        *c = c.saturating_add(1);
    }
}

/// Decodes COBS in place; returns the decoded length, or `None` when a block
/// runs past the end (or holds a zero, which a split at delimiters excludes).
fn cobs_decode_in_place(buf: &mut [u8]) -> Option<usize> {
    let n = buf.len();
    let (mut read, mut write) = (0usize, 0usize);
    while read < n {
        let code = *buf.get(read)?;
        read += 1;
        if code == 0 {
            return None;
        }
        let run = usize::from(code - 1);
        if read.checked_add(run)? > n {
            return None;
        }
        for _ in 0..run {
            let b = *buf.get(read)?;
            if b == 0 {
                return None;
            }
            *buf.get_mut(write)? = b;
            read += 1;
            write += 1;
        }
        if code != 0xFF && read < n {
            *buf.get_mut(write)? = 0;
            write += 1;
        }
    }
    Some(write)
}

/// Decodes one frame given without its delimiter, in place (the buffer is
/// overwritten).
pub fn decode_frame(frame: &mut [u8]) -> Result<Message, FrameError> {
    message_of(frame_payload(frame)?)
}

/// [`decode_frame`] with the message written into `msg` (what it held is
/// replaced; untouched on error). A message is ≈ 3 KB (a checkpoint's size,
/// whatever it holds): a firmware that keeps `msg` in static memory has no
/// second copy of it on its stack.
pub fn decode_frame_into(frame: &mut [u8], msg: &mut Message) -> Result<(), FrameError> {
    message_into(frame_payload(frame)?, msg)
}

/// The postcard payload of a frame (COBS decoded in place; length, CRC and
/// version checked).
fn frame_payload(frame: &mut [u8]) -> Result<&[u8], FrameError> {
    let n = cobs_decode_in_place(frame).ok_or(FrameError::Truncated)?;
    let raw = frame.get(..n).ok_or(FrameError::Truncated)?;
    if n < MIN_DECODED_LEN {
        return Err(FrameError::Truncated);
    }
    let (body, crc) = raw.split_at(n - CRC_LEN);
    let mut crc_bytes = [0u8; CRC_LEN];
    crc_bytes.copy_from_slice(crc);
    if crc32(body) != u32::from_le_bytes(crc_bytes) {
        return Err(FrameError::Corrupt);
    }
    let (&version, payload) = body.split_first().ok_or(FrameError::Truncated)?;
    if version != VERSION {
        return Err(FrameError::WrongVersion(version));
    }
    Ok(payload)
}

/// The message of a frame's payload: all of it, nothing left over.
fn message_of(payload: &[u8]) -> Result<Message, FrameError> {
    match postcard::take_from_bytes::<Message>(payload) {
        Ok((msg, [])) => Ok(msg),
        _ => Err(FrameError::Malformed),
    }
}

/// [`message_of`] written into `msg` (untouched on error). Out of line:
/// the decoding's copies of the message are in this frame only, not in
/// its callers'.
#[inline(never)]
fn message_into(payload: &[u8], msg: &mut Message) -> Result<(), FrameError> {
    match postcard::take_from_bytes::<Message>(payload) {
        Ok((m, [])) => {
            *msg = m;
            Ok(())
        }
        _ => Err(FrameError::Malformed),
    }
}

/// Streaming frame decoder over a fixed buffer of `CAP` bytes (use
/// [`FrameDecoder`] = `Decoder<MAX_FRAME_LEN>` to accept every message).
/// Bytes may arrive in chunks of any size; a rejected frame is counted in
/// [`Decoder::stats`] and skipped, and decoding resumes after the next
/// `0x00`. No input can make it panic.
#[derive(Clone, Debug)]
pub struct Decoder<const CAP: usize> {
    buf: [u8; CAP],
    len: usize,
    overflow: bool,
    stats: DecoderStats,
}

impl<const CAP: usize> Default for Decoder<CAP> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const CAP: usize> Decoder<CAP> {
    /// An empty decoder.
    pub const fn new() -> Self {
        Self {
            buf: [0; CAP],
            len: 0,
            overflow: false,
            stats: DecoderStats {
                ok: 0,
                corrupt: 0,
                malformed: 0,
                truncated: 0,
                oversized: 0,
                wrong_version: 0,
                empty: 0,
            },
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    /// Bytes of an unfinished frame held in the buffer.
    pub fn pending(&self) -> usize {
        self.len
    }

    /// Drops any unfinished frame (counters are kept).
    pub fn clear(&mut self) {
        self.len = 0;
        self.overflow = false;
    }

    /// Accepts one byte; at a delimiter returns the frame's outcome (already
    /// counted), otherwise `None`. Empty frames give `None`.
    // Not inlined: the decoder's temporaries stay out of the caller's
    // frame, which holds the message while it is handled (a firmware, whose
    // stack is small, uses `push_byte_into` and a static slot).
    #[inline(never)]
    pub fn push_byte(&mut self, byte: u8) -> Option<Result<Message, FrameError>> {
        self.push_byte_with(byte, decode_frame)
    }

    /// [`Decoder::push_byte`] with a decoded message written into `msg`
    /// (what it held is replaced; it is untouched when the frame is
    /// rejected): `Some(Ok(()))` when `msg` holds a new message. A message
    /// is ≈ 3 KB (a checkpoint's size, whatever it holds): a firmware that
    /// keeps `msg` in static memory has none in its frames
    /// ([`decode_frame_into`]).
    #[inline(never)]
    pub fn push_byte_into(
        &mut self,
        byte: u8,
        msg: &mut Message,
    ) -> Option<Result<(), FrameError>> {
        self.push_byte_with(byte, |frame| decode_frame_into(frame, msg))
    }

    /// Accepts one byte; at a delimiter decodes the frame with `decode`
    /// and counts the outcome.
    fn push_byte_with<R>(
        &mut self,
        byte: u8,
        decode: impl FnOnce(&mut [u8]) -> Result<R, FrameError>,
    ) -> Option<Result<R, FrameError>> {
        if byte != 0 {
            if self.overflow {
                return None;
            }
            match self.buf.get_mut(self.len) {
                Some(slot) => {
                    *slot = byte;
                    self.len += 1;
                }
                None => self.overflow = true,
            }
            return None;
        }
        let (len, overflow) = (self.len, self.overflow);
        self.clear();
        let result = if overflow {
            Err(FrameError::Oversized)
        } else if len == 0 {
            self.stats.empty = self.stats.empty.saturating_add(1);
            return None;
        } else {
            match self.buf.get_mut(..len) {
                Some(frame) => decode(frame),
                None => Err(FrameError::Oversized),
            }
        };
        self.stats.count(&result);
        Some(result)
    }

    /// Accepts a chunk of bytes and calls `on_frame` with the outcome of
    /// every frame it completes (rejected frames are also counted in
    /// [`Decoder::stats`]).
    pub fn feed_results(
        &mut self,
        chunk: &[u8],
        mut on_frame: impl FnMut(Result<Message, FrameError>),
    ) {
        for b in chunk {
            if let Some(r) = self.push_byte(*b) {
                on_frame(r);
            }
        }
    }

    /// Accepts a chunk of bytes and calls `on_message` with every message it
    /// completes; rejected frames are counted and skipped.
    pub fn feed(&mut self, chunk: &[u8], mut on_message: impl FnMut(Message)) {
        self.feed_results(chunk, |r| {
            if let Ok(m) = r {
                on_message(m);
            }
        });
    }
}
