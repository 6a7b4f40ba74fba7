//! Checkpoints: [`Calibrator::checkpoint`] and [`Calibrator::restore`],
//! which continues bit-identically.

use nalgebra::{Matrix3, RealField, SVector};

use super::{to_f64, Calibrator, Error};
use crate::ekf::{FilterConfig, Parts};
use crate::models::Model;
use crate::wire::{CalibratorConfig, Checkpoint};

impl<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>
    Calibrator<T, M, N, Z>
{
    /// A checkpoint from which [`Calibrator::restore`] continues
    /// bit-identically.
    // Not inlined: the session dispatches to seven of these, and their
    // frames must not add up in one caller's frame (firmware stack).
    #[inline(never)]
    pub fn checkpoint(&self) -> Checkpoint {
        let f = &self.filter;
        let collect = |v: &SVector<f64, N>| {
            let mut out = heapless::Vec::new();
            for x in v.iter() {
                let _ = out.push(*x);
            }
            out
        };
        let mut factor = heapless::Vec::new();
        // Row-major: the column-major storage of the transpose.
        for v in f.factor().transpose().iter() {
            let _ = factor.push(to_f64(*v));
        }
        let mut c_cn = [0.0; 9];
        for (o, v) in c_cn
            .iter_mut()
            .zip(f.command_frame().c_cn.transpose().iter())
        {
            *o = *v;
        }
        Checkpoint {
            config: M::ID,
            errors: M::ERRORS,
            state: collect(f.state()),
            factor,
            nominal: f.nominal().map(collect),
            c_cn,
            updates: f.updates(),
            gated_run: f.gate_state().0,
            gate_open: f.gate_state().1,
            progress: self.progress,
        }
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
        let vector = |v: &[f64]| {
            (v.len() == N)
                .then(|| SVector::<f64, N>::from_iterator(v.iter().copied()))
                .ok_or(Error::CheckpointDimension)
        };
        let x = vector(&cp.state)?;
        if cp.factor.len() != N * N {
            return Err(Error::CheckpointDimension);
        }
        let nominal = match &cp.nominal {
            Some(v) => Some(vector(v)?),
            None => None,
        };
        let c_cn = Matrix3::from_row_iterator(cp.c_cn.iter().copied());
        self.filter.set_parts(
            FilterConfig::from(&settings),
            &Parts {
                x: &x,
                factor: &cp.factor,
                c_cn: &c_cn,
                nominal: nominal.as_ref(),
                updates: cp.updates,
                gate_state: (cp.gated_run, cp.gate_open),
            },
        )?;
        self.settings = settings;
        self.progress = cp.progress;
        self.frame_errors = 0;
        Ok(())
    }
}
