//! Fuzzes the integration kit (`rollcal::device`): bytes from the input,
//! or the recorded paper stream's first frames altered by it, fed to a
//! `Device` over a NOR flash in RAM (a word written once between erases,
//! the `embedded-storage` alignment rules), with `idle` between frames; a
//! power cut after an operation the input picks (landing in part or not),
//! maybe bytes of the flash damaged, the device started again on what the
//! flash kept, the rest of the bytes, and a `Finish`.
//!
//! The device must never panic; it must never write a word twice without
//! an erase or outside the rules; and a flash only it wrote (no damage) is
//! never refused as another format's or as an undecodable frame.
#![no_main]

use embedded_storage::nor_flash::{
    check_erase, check_read, check_write, ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash,
};
use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use rollcal::device::{Device, ResumeRefusal};
use rollcal::wire::{encode, Message, MAX_FRAME_LEN};

const W: usize = 4;
const E: usize = 4096;
/// 2 control banks of 4 sectors and 4 sectors of log.
const SECTORS: usize = 12;
/// The recorded stream (`Configure` for M2-ps, then `Sample` frames).
const STREAM: &[u8] = include_bytes!("../../tests/data/paper_seed1.bin");
/// Bytes of the stream's first frames the target uses at most.
const STREAM_PREFIX: usize = 6_000;

struct Nor {
    mem: Vec<u8>,
    written: Vec<bool>,
    ops: usize,
    cut_at: Option<usize>,
    half: bool,
    dead: bool,
}

impl ErrorType for Nor {
    type Error = NorFlashErrorKind;
}

impl ReadNorFlash for Nor {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> core::result::Result<(), Self::Error> {
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

impl Nor {
    /// Whether this operation is cut; how many bytes of `len` land.
    fn cut_now(&mut self, len: usize) -> Option<usize> {
        self.ops += 1;
        if self.cut_at != Some(self.ops) {
            return None;
        }
        self.dead = true;
        Some(if self.half { len / 2 / W * W } else { 0 })
    }
}

impl NorFlash for Nor {
    const WRITE_SIZE: usize = W;
    const ERASE_SIZE: usize = E;
    fn erase(&mut self, from: u32, to: u32) -> core::result::Result<(), Self::Error> {
        if self.dead {
            return Err(NorFlashErrorKind::Other);
        }
        check_erase(self, from, to)?;
        let (from, to) = (from as usize, to as usize);
        let landed = self.cut_now(to - from);
        let end = from + landed.unwrap_or(to - from);
        self.mem[from..end].fill(0xFF);
        self.written[from / W..end / W].fill(false);
        match landed {
            Some(_) => Err(NorFlashErrorKind::Other),
            None => Ok(()),
        }
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> core::result::Result<(), Self::Error> {
        if self.dead {
            return Err(NorFlashErrorKind::Other);
        }
        check_write(self, offset, bytes.len())?;
        let at = offset as usize;
        for w in at / W..(at + bytes.len()) / W {
            assert!(!self.written[w], "word {w} written twice without an erase");
        }
        let n = self.cut_now(bytes.len()).unwrap_or(bytes.len());
        for (i, b) in bytes[..n].iter().enumerate() {
            self.mem[at + i] &= *b;
        }
        self.written[at / W..(at + n) / W].fill(true);
        if self.dead {
            return Err(NorFlashErrorKind::Other);
        }
        Ok(())
    }
}

fuzz_target!(|data: &[u8]| {
    let _ = run(&mut Unstructured::new(data));
});

fn run(u: &mut Unstructured<'_>) -> Result<()> {
    // The bytes the host sends: the recorded stream's start, altered, or
    // the input's own.
    let mut bytes: Vec<u8> = if u.ratio(3u8, 4u8)? {
        let n = u.int_in_range(0..=STREAM_PREFIX)?;
        let mut b = STREAM[..n].to_vec();
        for _ in 0..u.int_in_range(0u8..=4)? {
            if b.is_empty() {
                break;
            }
            let at = u.choose_index(b.len())?;
            b[at] = u.arbitrary()?;
        }
        b
    } else {
        let n = u.int_in_range(0..=2048)?;
        u.bytes(n)?.to_vec()
    };
    let mut finish = [0u8; MAX_FRAME_LEN];
    if let Ok(n) = encode(&Message::Finish, &mut finish) {
        bytes.extend_from_slice(&finish[..n]);
    }
    let flash = Nor {
        mem: vec![0; SECTORS * E],
        written: vec![true; SECTORS * E / W],
        ops: 0,
        cut_at: Some(u.int_in_range(1..=400)?),
        half: u.arbitrary()?,
        dead: false,
    };
    let region = 0..(SECTORS * E) as u32;
    let every = u.int_in_range(1u32..=20)?;
    let mut dev = Box::new(Device::<Nor, f64>::new());
    dev.set_checkpoint_every(every);
    let Ok(_) = dev.start(flash, region.clone()) else {
        panic!("the region fits");
    };
    let mut at = 0;
    while at < bytes.len() && !dev.log().is_some_and(|l| l.flash().dead) {
        let b = bytes[at];
        at += 1;
        let _ = dev.push_byte(b);
        if b == 0 && u.ratio(7u8, 8u8)? {
            dev.idle();
        }
    }
    let Some(mut flash) = dev.release() else {
        panic!("the device gives its flash back");
    };
    flash.dead = false;
    flash.cut_at = None;
    let damaged = u.ratio(1u8, 8u8)?;
    if damaged {
        for _ in 0..u.int_in_range(1u8..=8)? {
            let i = u.choose_index(flash.mem.len())?;
            flash.mem[i] = u.arbitrary()?;
        }
    }
    let mut dev = Box::new(Device::<Nor, f64>::new());
    dev.set_checkpoint_every(every);
    let resume = match dev.start(flash, region) {
        Ok(r) => r,
        Err(_) => panic!("the region fits"),
    };
    if !damaged {
        assert!(
            !matches!(
                resume.refused,
                Some(
                    ResumeRefusal::Format(_) | ResumeRefusal::Frame(_) | ResumeRefusal::Unexpected
                )
            ),
            "its own flash refused: {resume:?}"
        );
    }
    for &b in &bytes[at..] {
        let _ = dev.push_byte(b);
        if b == 0 {
            dev.idle();
        }
    }
    Ok(())
}
