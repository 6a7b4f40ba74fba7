//! Checkpoints: [`Calibrator::checkpoint`] and [`Calibrator::restore`],
//! which continues bit-identically.

use nalgebra::{Matrix3, RealField, SVector};

use super::{to_f64, Calibrator, Error};
use crate::ekf::{Filter, FilterConfig, Parts};
use crate::estimator::LogStart;
use crate::models::Model;
use crate::wire::{factor_len, CalibratorConfig, Checkpoint};

/// `v` becomes the values of `it`, in order (at most its capacity: the
/// calibrator's `N` is checked against [`crate::wire::MAX_STATES`] when it
/// is built, so a checkpoint's vectors hold every value).
fn fill<const CAP: usize>(v: &mut heapless::Vec<f64, CAP>, it: impl Iterator<Item = f64>) {
    v.clear();
    for x in it {
        let _ = v.push(x);
    }
}

impl<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>
    Calibrator<T, M, N, Z>
{
    /// A checkpoint from which [`Calibrator::restore`] continues
    /// bit-identically ([`Calibrator::checkpoint_into`] into a new one).
    pub fn checkpoint(&self) -> Checkpoint {
        let mut cp = Checkpoint::empty();
        self.checkpoint_into(&mut cp);
        cp
    }

    /// [`Calibrator::checkpoint`] written into `cp` (whatever it held),
    /// field by field: no checkpoint-sized temporary (≈ 12.8 KB with the
    /// full model's 54 states) on the stack, and no copy of the factor. A firmware that keeps `cp` in static memory (the reply
    /// slot of [`crate::session::Session::handle_into`]) checkpoints in a
    /// few hundred bytes of stack.
    // Not inlined: the session dispatches to seven of these, and their
    // frames must not add up in one caller's frame (firmware stack).
    #[inline(never)]
    pub fn checkpoint_into(&self, cp: &mut Checkpoint) {
        let f = &self.filter;
        cp.config = M::ID;
        cp.errors = M::ERRORS;
        fill(&mut cp.state, f.state().iter().copied());
        // The upper triangle, row by row.
        let factor = f.factor();
        fill(
            &mut cp.factor,
            (0..N)
                .flat_map(|r| (r..N).filter_map(move |c| factor.get((r, c)).copied().map(to_f64))),
        );
        match (f.nominal(), &mut cp.nominal) {
            (Some(n), Some(v)) => fill(v, n.iter().copied()),
            (Some(n), slot @ None) => {
                let mut v = heapless::Vec::new();
                fill(&mut v, n.iter().copied());
                *slot = Some(v);
            }
            (None, slot) => *slot = None,
        }
        for (o, v) in cp
            .c_cn
            .iter_mut()
            .zip(f.command_frame().c_cn.transpose().iter())
        {
            *o = *v;
        }
        cp.updates = f.updates();
        (cp.gated_run, cp.gate_open) = f.gate_state();
        cp.progress = self.progress;
    }

    /// A calibrator with settings `settings` continuing from checkpoint `cp`.
    // Not inlined: the session dispatches to seven of these, and their
    // frames must not add up in one caller's frame (firmware stack).
    #[inline(never)]
    pub fn restore(settings: CalibratorConfig, cp: &Checkpoint) -> Result<Self, Error> {
        let mut c = Self::new(settings)?;
        c.restore_in_place(settings, cp)?;
        Ok(c)
    }

    /// `*self = Calibrator::restore(settings, cp)?`, in place (the
    /// checkpoint is read where it is: no calibrator-sized or `N×N`
    /// temporary on the stack). On error the calibrator is unchanged.
    pub fn restore_in_place(
        &mut self,
        settings: CalibratorConfig,
        cp: &Checkpoint,
    ) -> Result<(), Error> {
        Self::check_config(settings.config, settings.errors)?;
        Self::check_config(cp.config, cp.errors)?;
        if let Some(field) = settings.invalid_field() {
            return Err(Error::InvalidField(field));
        }
        set_filter(&mut self.filter, FilterConfig::from(&settings), cp)?;
        self.settings = settings;
        self.progress = cp.progress;
        self.frame_errors = 0;
        self.start = LogStart::aligned();
        Ok(())
    }

    /// The filter put back from `saved`, its own checkpoint
    /// ([`Calibrator::finish_in_place`]), with the calibrator's settings
    /// (which its filter was built or restored with): the filter only (the
    /// bookkeeping, the log's start and the frame errors are the
    /// calibrator's, which the passes do not touch).
    pub(super) fn put_back(&mut self, saved: &Checkpoint) -> Result<(), Error> {
        set_filter(&mut self.filter, FilterConfig::from(&self.settings), saved)
    }
}

/// `f` becomes the filter `cp` saved, with settings `config`; every part is
/// checked first (on error `f` is unchanged).
// Not inlined: its vectors are not in the frames of its callers.
#[inline(never)]
fn set_filter<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize>(
    f: &mut Filter<T, M, N, Z>,
    config: FilterConfig<T>,
    cp: &Checkpoint,
) -> Result<(), Error> {
    let vector = |v: &[f64]| {
        (v.len() == N)
            .then(|| SVector::<f64, N>::from_iterator(v.iter().copied()))
            .ok_or(Error::CheckpointDimension)
    };
    let x = vector(&cp.state)?;
    if cp.factor.len() != factor_len(N) {
        return Err(Error::CheckpointDimension);
    }
    let c_cn = Matrix3::from_row_iterator(cp.c_cn.iter().copied());
    if !is_rotation(&c_cn) {
        return Err(Error::CheckpointInvalid);
    }
    let nominal = match &cp.nominal {
        Some(v) => Some(vector(v)?),
        None => None,
    };
    f.set_parts(
        config,
        &Parts {
            x: &x,
            factor: &cp.factor,
            c_cn: &c_cn,
            nominal: nominal.as_ref(),
            updates: cp.updates,
            gate_state: (cp.gated_run, cp.gate_open),
        },
    )?;
    Ok(())
}

/// How far from orthonormal (`|CᵀC − I|`, any entry) a restored computed
/// frame may be. The filter advances its frame by rotations, so it leaves
/// orthonormality only by rounding, and steadily: on the paper's stream
/// 8.6e-18 a period in f64 and 3.2e-14 in f32 (whose turn of each period
/// is formed in f32), 3e-12 a period in f32 at the session fuzz target's
/// 0.03 rad a period. 1e-4 leaves room for 3e7 such periods and still
/// refuses a frame that is not a rotation.
const FRAME_TOLERANCE: f64 = 1e-4;

/// Whether `c` is a rotation: `CᵀC = I` within [`FRAME_TOLERANCE`] in
/// every entry and `det C > 0`. False for a non-finite `c`.
fn is_rotation(c: &Matrix3<f64>) -> bool {
    let e = c.transpose() * c - Matrix3::identity();
    e.iter().all(|v| v.abs() <= FRAME_TOLERANCE) && c.determinant() > 0.0
}
