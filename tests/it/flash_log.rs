//! The sample log in NOR flash (`rollcal::estimator::FlashLog`) against a
//! model of a NOR device with the `embedded-storage` semantics: a word is
//! written once between erases and only where every bit is erased,
//! offsets and lengths aligned to the write, read and erase sizes, and a
//! power cut after any write or erase, the operation cut landing in part.
//!
//! - the paper's run (5400 periods) through the calibrator: the estimator
//!   of record's answer is bit for bit the one over the same packed records
//!   in RAM (`PackedLog`), within 0.01σ of the one over the unrounded
//!   records (`SliceLog`; the packed rounding alone, as host-sim's
//!   `packed_log` test measures), and again after the log is reopened;
//!   bytes per period and the log's size printed;
//! - a cut after every operation of a shorter run with truncations: the
//!   reopened log holds exactly the records whose append returned `Ok`,
//!   and goes on from there;
//! - truncation, the segment table, refused geometries and records.

#![cfg(feature = "flash-log")]

use embedded_storage::nor_flash::{
    check_erase, check_read, check_write, ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash,
};
use rollcal::calibrator::{M1PaCalibrator, M2PsCalibrator};
use rollcal::estimator::{
    EstimatorOptions, FlashLog, FlashLogError, LogError, LogRecord, PackedLayout, PackedLog,
    SampleLog, SliceLog, MAX_PERIODS,
};
use rollcal::models::ConfigId;
use rollcal::wire::{Estimate, EstimateKind};

use crate::support::{log_record, paper_stream, settings};

/// How much of the operation a power cut interrupts lands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Cut {
    /// None of it.
    Nothing,
    /// Its first half (whole words).
    Half,
    /// All but its last word.
    AllButOneWord,
}

/// A NOR flash in RAM: `R`-byte reads, `W`-byte words, `E`-byte sectors.
#[derive(Clone, Debug)]
pub(crate) struct Nor<const R: usize, const W: usize, const E: usize> {
    pub(crate) mem: Vec<u8>,
    /// Per word: written since its sector's last erase.
    written: Vec<bool>,
    /// Writes and erases so far.
    pub(crate) ops: usize,
    /// The operation (1-based) the power cut interrupts.
    cut_at: Option<usize>,
    cut: Cut,
    /// Power is off: every operation fails.
    pub(crate) dead: bool,
    writes: usize,
    erases: usize,
}

impl<const R: usize, const W: usize, const E: usize> Nor<R, W, E> {
    /// A device of `sectors` sectors as shipped: every bit programmed (0),
    /// so that nothing is taken for erased before the log erases it.
    pub(crate) fn new(sectors: usize) -> Self {
        Self {
            mem: vec![0; sectors * E],
            written: vec![true; sectors * E / W],
            ops: 0,
            cut_at: None,
            cut: Cut::Nothing,
            dead: false,
            writes: 0,
            erases: 0,
        }
    }

    pub(crate) fn cut_after(mut self, ops: usize, cut: Cut) -> Self {
        self.cut_at = Some(ops + 1);
        self.cut = cut;
        self
    }

    /// Power back on.
    pub(crate) fn revive(mut self) -> Self {
        self.dead = false;
        self.cut_at = None;
        self
    }

    /// Whether this operation is the one cut: it then lands `n` bytes of
    /// `len` and the power goes.
    fn cut_now(&mut self, len: usize) -> Option<usize> {
        self.ops += 1;
        if self.cut_at != Some(self.ops) {
            return None;
        }
        self.dead = true;
        Some(match self.cut {
            Cut::Nothing => 0,
            Cut::Half => len / 2 / W * W,
            Cut::AllButOneWord => len - W,
        })
    }
}

impl<const R: usize, const W: usize, const E: usize> ErrorType for Nor<R, W, E> {
    type Error = NorFlashErrorKind;
}

impl<const R: usize, const W: usize, const E: usize> ReadNorFlash for Nor<R, W, E> {
    const READ_SIZE: usize = R;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        if self.dead {
            return Err(NorFlashErrorKind::Other);
        }
        check_read(self, offset, bytes.len())?;
        let at = offset as usize;
        bytes.copy_from_slice(&self.mem[at..at + bytes.len()]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.mem.len()
    }
}

impl<const R: usize, const W: usize, const E: usize> NorFlash for Nor<R, W, E> {
    const WRITE_SIZE: usize = W;
    const ERASE_SIZE: usize = E;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if self.dead {
            return Err(NorFlashErrorKind::Other);
        }
        check_erase(self, from, to)?;
        let (from, to) = (from as usize, to as usize);
        let landed = self.cut_now(to - from);
        let end = from + landed.unwrap_or(to - from);
        self.mem[from..end].fill(0xFF);
        self.written[from / W..end / W].fill(false);
        self.erases += 1;
        match landed {
            Some(_) => Err(NorFlashErrorKind::Other),
            None => Ok(()),
        }
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        if self.dead {
            return Err(NorFlashErrorKind::Other);
        }
        check_write(self, offset, bytes.len())?;
        let at = offset as usize;
        for w in at / W..(at + bytes.len()) / W {
            assert!(!self.written[w], "word {w} written twice without an erase");
        }
        let landed = self.cut_now(bytes.len());
        let n = landed.unwrap_or(bytes.len());
        for (i, b) in bytes[..n].iter().enumerate() {
            let old = self.mem[at + i];
            assert_eq!(old & b, *b, "byte {} programmed from 0 to 1", at + i);
            self.mem[at + i] = *b;
        }
        self.written[at / W..(at + n) / W].fill(true);
        self.writes += 1;
        match landed {
            Some(_) => Err(NorFlashErrorKind::Other),
            None => Ok(()),
        }
    }
}

/// The paper stream's records (f64), gimbal angles dropped for `Accel`.
fn records(layout: PackedLayout, n: usize) -> Vec<LogRecord<f64>> {
    let (_, samples) = paper_stream();
    samples[..n]
        .iter()
        .map(|s| {
            let mut r = log_record(s);
            if layout == PackedLayout::Accel {
                if let Some(o) = r.observation.as_mut() {
                    o.gimbal = None;
                }
            }
            r
        })
        .collect()
}

/// `records` as the packed encoding gives them back.
fn packed(layout: PackedLayout, records: &[LogRecord<f64>]) -> Vec<LogRecord<f64>> {
    let mut bytes = vec![0u8; records.len() * layout.record_len()];
    let mut table = [0.0; MAX_PERIODS];
    let mut log = PackedLog::new(&mut bytes, &mut table, layout);
    for r in records {
        log.append(r).unwrap();
    }
    (0..records.len()).map(|k| log.get(k).unwrap()).collect()
}

/// Every record of `log`.
fn contents(log: &mut dyn SampleLog<f64>) -> Vec<LogRecord<f64>> {
    (0..log.len())
        .map(|k| {
            log.get(k)
                .unwrap_or_else(|| panic!("record {k} reads back"))
        })
        .collect()
}

/// The estimate's numbers, bit for bit (NaN fields included).
fn bits(e: &Estimate) -> String {
    format!("{e:?}")
}

macro_rules! paper_run {
    ($cal:ty, $id:expr, $layout:expr, $slot:expr) => {{
        let id = $id;
        let layout = $layout;
        let cfg = settings(id, 0);
        let (_, mut samples) = paper_stream();
        if layout == PackedLayout::Accel {
            // The accelerometer-only layout stores no gimbal angles (and
            // refuses a record with them): a platform without resolvers.
            for s in &mut samples {
                s.gimbal = None;
            }
        }
        let opts = EstimatorOptions::default();
        // The device: 4-byte words, 4 KiB sectors, sized for the run.
        type Dev = Nor<1, 4, 4096>;
        let slot = FlashLog::<Dev, f64>::slot_len_of(layout);
        assert_eq!(slot, $slot);
        let per_sector = 4096 / slot;
        let sectors = samples.len().div_ceil(per_sector);
        let region = 0..(sectors * 4096) as u32;
        let mut flash = FlashLog::<Dev, f64>::open(Dev::new(sectors), region.clone(), layout)
            .expect("a blank region opens");
        assert_eq!(flash.len(), 0);
        let mut cal = <$cal>::new(cfg).unwrap();
        for s in &samples {
            cal.push_logged(s, &mut flash).unwrap();
        }
        assert_eq!(cal.progress().log_incomplete, None);
        assert_eq!(flash.len(), samples.len());
        // The same calibration over the packed records in RAM and over the
        // unrounded ones.
        let mut bytes = vec![0u8; samples.len() * layout.record_len()];
        let mut table = [0.0; MAX_PERIODS];
        let mut in_ram = PackedLog::new(&mut bytes, &mut table, layout);
        let mut storage =
            vec![LogRecord::predicted(1.0, nalgebra::Vector3::zeros()); samples.len()];
        let mut full = SliceLog::new(&mut storage);
        let mut cal_ram = <$cal>::new(cfg).unwrap();
        let mut cal_full = <$cal>::new(cfg).unwrap();
        for s in &samples {
            cal_ram.push_logged(s, &mut in_ram).unwrap();
            cal_full.push_logged(s, &mut full).unwrap();
        }
        assert_eq!(contents(&mut flash), contents(&mut in_ram));
        let (on_flash, _) = cal.finish(&mut flash, &opts, |_| {});
        let (on_ram, _) = cal_ram.finish(&mut in_ram, &opts, |_| {});
        let (on_full, _) = cal_full.finish(&mut full, &opts, |_| {});
        assert!(
            matches!(on_flash.kind, EstimateKind::Final { .. }),
            "{:?}",
            on_flash.kind
        );
        assert_eq!(bits(&on_flash), bits(&on_ram));
        let worst = on_flash
            .state
            .iter()
            .zip(&on_full.state)
            .zip(&on_full.sigma)
            .map(|((a, b), s)| ((a - b) / s).abs())
            .fold(0.0f64, f64::max);
        assert!(
            worst < 0.01,
            "{}: the flash log moved the answer by {worst:.3e}σ",
            id.as_str()
        );
        // After a reset: the run read back from the device, the same answer.
        let dev = flash.into_inner();
        let (writes, erases) = (dev.writes, dev.erases);
        assert_eq!(writes, samples.len());
        assert_eq!(erases, sectors);
        let mut reopened = FlashLog::<Dev, f64>::open(dev, region, layout).unwrap();
        assert_eq!(reopened.len(), samples.len());
        let (again, _) = cal.finish(&mut reopened, &opts, |_| {});
        assert_eq!(bits(&again), bits(&on_flash));
        let used = sectors * 4096;
        eprintln!(
            "{}: {} B per period on a NOR flash of 4-byte words and 4 KiB sectors \
             ({} B of record); {} periods: {} B in slots, {} sectors = {} B ({:.0} KiB); \
             |Δx|/σ vs the unrounded log {worst:.2e}",
            id.as_str(),
            slot,
            layout.record_len(),
            samples.len(),
            samples.len() * slot,
            sectors,
            used,
            used as f64 / 1024.0
        );
        (slot, used)
    }};
}

#[test]
fn the_paper_run_on_flash_gives_the_packed_logs_answer_bit_for_bit() {
    let (slot, used) = paper_run!(
        M2PsCalibrator<f64>,
        ConfigId::M2Ps,
        PackedLayout::AccelGimbal,
        52
    );
    assert_eq!((slot, used), (52, 70 * 4096));
    let (slot, used) = paper_run!(M1PaCalibrator<f64>, ConfigId::M1Pa, PackedLayout::Accel, 44);
    assert_eq!((slot, used), (44, 59 * 4096));
}

/// One step of the script a cut interrupts.
#[derive(Clone, Copy, Debug)]
enum Step {
    Append(usize),
    Truncate(usize),
}

/// The script: records 0–13, back to 9 records (a checkpoint restored),
/// records 14–24, back to none (a reset), records 25–33.
fn script() -> Vec<Step> {
    let mut s: Vec<Step> = (0..14).map(Step::Append).collect();
    s.push(Step::Truncate(9));
    s.extend((14..25).map(Step::Append));
    s.push(Step::Truncate(0));
    s.extend((25..34).map(Step::Append));
    s
}

/// The device after a script, the log as of the last append that returned
/// `Ok`, and the log it was truncated to after that, if it was.
type Outcome<D> = (D, Vec<LogRecord<f64>>, Option<Vec<LogRecord<f64>>>);

/// Runs the script on `dev` until an append fails. Returns the device, the
/// log as of the last append that returned `Ok` (records completely
/// written), and the log it was truncated to after that, if it was.
fn run<const R: usize, const W: usize, const E: usize>(
    dev: Nor<R, W, E>,
    region: std::ops::Range<u32>,
    layout: PackedLayout,
    recs: &[LogRecord<f64>],
) -> Outcome<Nor<R, W, E>> {
    let mut log = FlashLog::<_, f64>::open(dev, region, layout).unwrap();
    let mut durable: Vec<LogRecord<f64>> = Vec::new();
    let mut pending: Option<Vec<LogRecord<f64>>> = None;
    for step in script() {
        match step {
            Step::Append(i) => {
                if log.append(&recs[i]).is_err() {
                    break;
                }
                let mut now = pending.take().unwrap_or_else(|| durable.clone());
                now.push(recs[i]);
                durable = now;
            }
            Step::Truncate(n) => {
                log.truncate(n);
                let mut now = pending.take().unwrap_or_else(|| durable.clone());
                now.truncate(n);
                pending = Some(now);
            }
        }
    }
    (log.into_inner(), durable, pending)
}

fn cut_everywhere<const R: usize, const W: usize, const E: usize>(layout: PackedLayout) {
    let recs = records(layout, 40);
    let expected = packed(layout, &recs);
    let decoded = |log: &[LogRecord<f64>]| -> Vec<LogRecord<f64>> {
        log.iter()
            .map(|r| expected[recs.iter().position(|x| x == r).unwrap()])
            .collect()
    };
    // Room for the run, the slots a truncation leaves behind and a skip.
    let per_sector = E / FlashLog::<Nor<R, W, E>, f64>::slot_len_of(layout);
    let sectors = 40usize.div_ceil(per_sector) + 1;
    let region = E as u32..(E * (sectors + 1)) as u32;
    let (whole, all, _) = run(
        Nor::<R, W, E>::new(sectors + 1),
        region.clone(),
        layout,
        &recs,
    );
    assert_eq!(all.len(), 9);
    let ops = whole.ops;
    assert!(
        whole.erases >= 4,
        "the run crosses sectors ({} erases)",
        whole.erases
    );
    let mut cases = 0;
    for cut in [Cut::Nothing, Cut::Half, Cut::AllButOneWord] {
        for k in 0..ops {
            let dev = Nor::<R, W, E>::new(sectors + 1).cut_after(k, cut);
            let (dev, durable, pending) = run(dev, region.clone(), layout, &recs);
            assert!(dev.dead, "the cut after {k} operations happened");
            let mut log = FlashLog::<_, f64>::open(dev.revive(), region.clone(), layout).unwrap();
            let back = contents(&mut log);
            let what = format!("{cut:?} cut after {k} of {ops} operations");
            match &pending {
                // Nothing appended since a truncation: the records it
                // forgot come back (then truncated again by the calibrator),
                // all of them, or a prefix when the cut was in the erase
                // that began a new run.
                Some(_) => {
                    let old = decoded(&durable);
                    assert!(
                        back.len() <= old.len() && back[..] == old[..back.len()],
                        "{what}: {} records back, not a prefix of the {} before the truncation",
                        back.len(),
                        old.len()
                    );
                }
                None => assert_eq!(back, decoded(&durable), "{what}"),
            }
            // The log goes on after the cut, and a reopen finds it all.
            let base = back.len();
            for r in &recs[34..40] {
                log.append(r)
                    .unwrap_or_else(|e| panic!("{what}: append after resume: {e}"));
            }
            let mut again =
                FlashLog::<_, f64>::open(log.into_inner(), region.clone(), layout).unwrap();
            let more = contents(&mut again);
            assert_eq!(more.len(), base + 6, "{what}");
            assert_eq!(&more[..base], &back[..], "{what}");
            assert_eq!(&more[base..], &expected[34..40], "{what}");
            cases += 1;
        }
    }
    eprintln!(
        "{layout:?}, R={R} W={W} E={E}: {cases} cuts, {ops} operations per run, every one resumed"
    );
}

#[test]
fn a_cut_after_any_write_or_erase_loses_at_most_the_record_being_written() {
    cut_everywhere::<1, 4, 256>(PackedLayout::Accel);
    cut_everywhere::<4, 8, 512>(PackedLayout::AccelGimbal);
    cut_everywhere::<1, 1, 128>(PackedLayout::Accel);
}

#[test]
fn truncation_starts_a_segment_and_survives_a_reopen() {
    type Dev = Nor<1, 4, 256>;
    let layout = PackedLayout::Accel;
    let recs = records(layout, 40);
    let expected = packed(layout, &recs);
    let region = 0..256 * 10;
    let mut log = FlashLog::<Dev, f64, 2>::open(Dev::new(10), region.clone(), layout).unwrap();
    assert_eq!(log.capacity(), 50);
    for r in &recs[..20] {
        log.append(r).unwrap();
    }
    log.truncate(12);
    assert_eq!(log.len(), 12);
    assert_eq!(log.get(12), None);
    for r in &recs[20..25] {
        log.append(r).unwrap();
    }
    assert_eq!(log.segments(), 2);
    let want: Vec<_> = expected[..12]
        .iter()
        .chain(&expected[20..25])
        .copied()
        .collect();
    assert_eq!(contents(&mut log), want);
    let mut log = FlashLog::<Dev, f64, 2>::open(log.into_inner(), region.clone(), layout).unwrap();
    assert_eq!(contents(&mut log), want);
    assert_eq!(log.free(), 50 - 25);
    // A third segment does not fit a table of two.
    log.truncate(15);
    assert_eq!(log.append(&recs[0]), Err(LogError::Full));
    assert_eq!(log.len(), 15);
    // Back into the first segment: the second is dropped, a new one fits.
    log.truncate(3);
    log.append(&recs[26]).unwrap();
    assert_eq!(log.segments(), 2);
    let mut want: Vec<_> = expected[..3].to_vec();
    want.push(expected[26]);
    assert_eq!(contents(&mut log), want);
    // A new run: from the region's start, the old one gone after a reopen.
    log.truncate(0);
    for r in &recs[30..33] {
        log.append(r).unwrap();
    }
    let mut log = FlashLog::<Dev, f64, 2>::open(log.into_inner(), region, layout).unwrap();
    assert_eq!(contents(&mut log), expected[30..33].to_vec());
    assert_eq!(log.free(), 50 - 3);
    assert_eq!(log.segments(), 1);
}

#[test]
fn formatted_regions_fill_without_erasing_and_full_logs_say_so() {
    type Dev = Nor<1, 4, 256>;
    let layout = PackedLayout::Accel;
    let recs = records(layout, 20);
    let mut log = FlashLog::<Dev, f64>::open(Dev::new(2), 0..512, layout).unwrap();
    log.format().unwrap();
    let mut dev = log.into_inner();
    assert_eq!(dev.erases, 1);
    dev.erases = 0;
    // A formatted region is known erased after a reopen.
    let mut log = FlashLog::<Dev, f64>::open(dev, 0..512, layout).unwrap();
    for r in &recs[..10] {
        log.append(r).unwrap();
    }
    assert_eq!(log.append(&recs[10]), Err(LogError::Full));
    assert_eq!(log.len(), 10);
    assert_eq!(log.into_inner().erases, 0);
}

#[test]
fn refused_regions_devices_and_records() {
    type Dev = Nor<1, 4, 256>;
    let layout = PackedLayout::Accel;
    let open = |region: std::ops::Range<u32>| {
        FlashLog::<Dev, f64>::open(Dev::new(4), region, layout).map(|_| ())
    };
    assert_eq!(open(0..1024), Ok(()));
    assert_eq!(open(100..1024), Err(FlashLogError::Region));
    assert_eq!(open(0..1000), Err(FlashLogError::Region));
    assert_eq!(open(0..2048), Err(FlashLogError::Region));
    assert_eq!(open(512..512), Err(FlashLogError::Region));
    // Sectors smaller than a slot.
    let tiny = FlashLog::<Nor<1, 4, 32>, f64>::open(Nor::new(4), 0..128, layout);
    assert_eq!(tiny.err(), Some(FlashLogError::Geometry));
    // A dead device.
    let mut dead = Dev::new(4);
    dead.dead = true;
    let err = FlashLog::<Dev, f64>::open(dead, 0..1024, layout).err();
    assert_eq!(err, Some(FlashLogError::Flash(NorFlashErrorKind::Other)));
    // A period that is not an f32, gimbal angles the layout does not store.
    let mut log = FlashLog::<Dev, f64>::open(Dev::new(4), 0..1024, layout).unwrap();
    let r = records(PackedLayout::AccelGimbal, 1)[0];
    assert_eq!(log.append(&r), Err(LogError::Unrepresentable));
    let mut odd = records(layout, 1)[0];
    odd.dt = 0.1;
    assert_eq!(log.append(&odd), Err(LogError::Unrepresentable));
    assert_eq!(log.len(), 0);
    // A device that fails a write: Storage, the slot skipped, the log goes on.
    let mut log =
        FlashLog::<Dev, f64>::open(Dev::new(4).cut_after(1, Cut::Half), 0..1024, layout).unwrap();
    let recs = records(layout, 3);
    log.append(&recs[0]).unwrap_err(); // the erase succeeded, the write is cut
    assert_eq!(log.last_error(), Some(NorFlashErrorKind::Other));
    let mut dev = log.into_inner().revive();
    dev.ops = 0;
    let mut log = FlashLog::<Dev, f64>::open(dev, 0..1024, layout).unwrap();
    assert_eq!(log.len(), 0);
    log.append(&recs[1]).unwrap();
    assert_eq!(contents(&mut log), packed(layout, &recs[1..2]));
}
