//! fogtemp firmware harness for QEMU `mps2-an386` (Cortex-M4F, `thumbv7em-none-eabihf`).
//!
//! What it does, in order:
//! 1. prints the FPU state (CPACR, FPSCR) so a run log shows the FPU is on and
//!    flush-to-zero / default-NaN are off;
//! 2. runs a small f32 self-test whose exact bit results were computed on the
//!    x86_64 host with the same Rust code, and fails the run on any mismatch;
//! 3. replays the embedded trajectory (`replay`) and prints one `out ...` line
//!    per output, f32 values as `to_bits()` hex so host-vs-target checks are exact;
//! 4. exits QEMU through semihosting: status 0 on success, 1 on failure
//!    (a panic also exits with 1, via `panic-semihosting`'s `exit` feature).
//!
//! Output line grammar (one record per line, space separated):
//! * `out <index> <rate bits, 8 lowercase hex digits>` — placeholder replay;
//!   the real replay will append ` <flags>` (see `replay`).
//! * `done outputs=<n>` — last line of a successful run.

#![no_std]
#![no_main]

use core::fmt::{self, Write as _};
use core::hint::black_box;

use cortex_m_rt::entry;
use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};
use cortex_m_semihosting::{hio, hprintln};
use panic_semihosting as _;

// Linked but not called yet: keeps the core crate building for the target.
use fogtemp_core as _;

/// Model blob, staged by build.rs from `$FOGTEMP_FW_MODEL` (empty by default).
static MODEL_BLOB: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/model.bin"));

/// Trajectory records, staged by build.rs from `$FOGTEMP_FW_TRAJECTORY`
/// (default `data/dummy_trajectory.bin`, 8 records).
static TRAJECTORY: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/trajectory.bin"));

#[entry]
fn main() -> ! {
    hprintln!("fogtemp firmware-qemu: start");
    report_fpu();

    let mut ok = selftest();

    let mut out = HostOut::new();
    match replay(&mut out, MODEL_BLOB, TRAJECTORY) {
        Ok(n) => {
            out.flush();
            hprintln!("done outputs={}", n);
        }
        Err(e) => {
            out.flush();
            hprintln!("error replay: {:?}", e);
            ok = false;
        }
    }

    exit(ok)
}

/// Leave QEMU through semihosting `SYS_EXIT`: status 0 for `true`, 1 for `false`.
fn exit(ok: bool) -> ! {
    debug::exit(if ok { EXIT_SUCCESS } else { EXIT_FAILURE });
    // Only reached when no semihosting host honours the exit (e.g. a real board
    // under a debugger that resumes): park the core.
    loop {
        cortex_m::asm::wfi();
    }
}

// ---------------------------------------------------------------------------
// FPU state
// ---------------------------------------------------------------------------

/// Print CPACR (CP10/CP11 access, set by cortex-m-rt's reset handler for
/// `-eabihf` targets) and FPSCR (FZ = bit 24, DN = bit 25, RMode = bits 23:22).
fn report_fpu() {
    let cpacr = match cortex_m::Peripherals::take() {
        Some(p) => p.SCB.cpacr.read(),
        None => 0,
    };
    let fpscr = cortex_m::register::fpscr::read();
    hprintln!(
        "fpu cpacr={:08x} cp10_cp11_full={} fpscr={:08x} fz={} dn={} rmode={}",
        cpacr,
        (cpacr >> 20) & 0xf == 0xf,
        fpscr.bits(),
        fpscr.fz() as u8,
        fpscr.dn() as u8,
        (fpscr.bits() >> 22) & 0b11,
    );
}

// ---------------------------------------------------------------------------
// f32 self-test
// ---------------------------------------------------------------------------

/// Sequential f32 harmonic sum 1/1 + ... + 1/n (vdiv.f32 + vadd.f32).
#[inline(never)]
fn harmonic(n: u32) -> f32 {
    let mut s = 0.0f32;
    let mut k = 1u32;
    while k <= n {
        s += 1.0 / k as f32;
        k += 1;
    }
    s
}

/// Sum of a cubic in Horner form over t = -40, -39.5, ... (n points):
/// the same shape of arithmetic as a temperature-drift polynomial.
#[inline(never)]
fn horner_sum(n: u32) -> f32 {
    let (c0, c1, c2, c3) = (
        black_box(0.75f32),
        black_box(-0.0125f32),
        black_box(3.5e-4f32),
        black_box(-2.0e-6f32),
    );
    let mut acc = 0.0f32;
    let mut i = 0u32;
    while i < n {
        let t = -40.0f32 + 0.5 * i as f32;
        acc += ((c3 * t + c2) * t + c1) * t + c0;
        i += 1;
    }
    acc
}

/// Run the checks; expected bits come from the identical code run on x86_64
/// (Rust never contracts a*b+c into an FMA, so results are bit-identical).
fn selftest() -> bool {
    // (name, got, expected bits)
    let checks = [
        ("harmonic1000", harmonic(black_box(1000)), 0x40ef_890a_u32), // 7.4854784
        ("horner256", horner_sum(black_box(256)), 0x4368_34db_u32),   // 232.20647
        // MIN_POSITIVE / 4 is subnormal: 0 here would mean flush-to-zero is on.
        (
            "subnormal",
            black_box(f32::MIN_POSITIVE) * black_box(0.25f32),
            0x0020_0000_u32,
        ),
    ];
    let mut all = true;
    for (name, got, want) in checks {
        let pass = got.to_bits() == want;
        all &= pass;
        hprintln!(
            "selftest {} {:08x} want {:08x} {}",
            name,
            got.to_bits(),
            want,
            if pass { "ok" } else { "MISMATCH" }
        );
    }
    all
}

// ---------------------------------------------------------------------------
// Trajectory records
// ---------------------------------------------------------------------------

/// Bytes per trajectory record: `u64 time_us, f32 gyro_dph, f32 temp_c`, little-endian.
const RECORD_LEN: usize = 16;

/// One decoded trajectory record.
#[derive(Clone, Copy, Debug)]
struct Record {
    /// Sample time in microseconds.
    #[allow(dead_code)] // used once the real Compensator replay is wired in
    time_us: u64,
    /// Raw gyro rate in deg/h.
    gyro_dph: f32,
    /// Sensor temperature in deg C.
    temp_c: f32,
}

impl Record {
    fn decode(b: &[u8; RECORD_LEN]) -> Self {
        let [t0, t1, t2, t3, t4, t5, t6, t7, g0, g1, g2, g3, c0, c1, c2, c3] = *b;
        Record {
            time_us: u64::from_le_bytes([t0, t1, t2, t3, t4, t5, t6, t7]),
            gyro_dph: f32::from_le_bytes([g0, g1, g2, g3]),
            temp_c: f32::from_le_bytes([c0, c1, c2, c3]),
        }
    }
}

/// Why a replay could not run.
#[derive(Debug)]
#[allow(dead_code)] // fields are read through Debug
enum ReplayError {
    /// Trajectory length is not a multiple of [`RECORD_LEN`].
    TrajectoryLength(usize),
}

// ===========================================================================
// REPLAY — PLACEHOLDER
//
// Final form (once fogtemp-core's API lands):
//   * build the compensator from `model` (the embedded model blob),
//   * for every record call `fogtemp_core::Compensator::step(...)`,
//   * for every output print
//       `out <index> <{:08x} of rate.to_bits()> <flags>`
//
// For now: no model, and a trivial stand-in computation per record,
//   rate = gyro_dph - 0.05 * (temp_c - 25.0)      (all f32)
// printed as `out <index> <hex bits>`. data/expected_out.txt holds the host
// result for data/dummy_trajectory.bin (from data/make_dummy_trajectory.py)
// and .ci/firmware-qemu.sh compares against it.
// ===========================================================================
fn replay(out: &mut HostOut, model: &[u8], trajectory: &[u8]) -> Result<u32, ReplayError> {
    let _ = model; // placeholder: the model blob is not interpreted yet

    if trajectory.len() % RECORD_LEN != 0 {
        return Err(ReplayError::TrajectoryLength(trajectory.len()));
    }
    let k = black_box(0.05f32);
    let t0 = black_box(25.0f32);

    let mut n = 0u32;
    for (index, chunk) in trajectory.chunks_exact(RECORD_LEN).enumerate() {
        let mut buf = [0u8; RECORD_LEN];
        buf.copy_from_slice(chunk);
        let rec = Record::decode(&buf);

        let rate = rec.gyro_dph - k * (rec.temp_c - t0);

        out.line(format_args!("out {} {:08x}", index, rate.to_bits()));
        n += 1;
    }
    Ok(n)
}

// ---------------------------------------------------------------------------
// Buffered semihosting output
// ---------------------------------------------------------------------------

/// Collects whole lines and hands them to the host in large chunks: every
/// semihosting call is a trap into QEMU, and `hprintln!` issues one per
/// formatting fragment, which gets slow for long replays.
struct HostOut {
    stream: Option<hio::HostStream>,
    buf: [u8; 1024],
    len: usize,
}

/// Longest single line `HostOut::line` accepts; longer lines are truncated.
const MAX_LINE: usize = 120;

impl HostOut {
    fn new() -> Self {
        HostOut {
            stream: hio::hstdout().ok(),
            buf: [0; 1024],
            len: 0,
        }
    }

    /// Append one formatted line plus `\n`.
    fn line(&mut self, args: fmt::Arguments<'_>) {
        if self.buf.len() - self.len < MAX_LINE + 1 {
            self.flush();
        }
        let start = self.len;
        let mut w = SliceWriter {
            buf: &mut self.buf[start..start + MAX_LINE],
            len: 0,
        };
        let _ = w.write_fmt(args); // truncated on overflow
        self.len = start + w.len;
        self.buf[self.len] = b'\n';
        self.len += 1;
    }

    fn flush(&mut self) {
        if let Some(s) = self.stream.as_mut() {
            let _ = s.write_all(&self.buf[..self.len]);
        }
        self.len = 0;
    }
}

/// `fmt::Write` into a fixed slice; errors (and stops) when full.
struct SliceWriter<'a> {
    buf: &'a mut [u8],
    len: usize,
}

impl fmt::Write for SliceWriter<'_> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        let room = self.buf.len() - self.len;
        let n = s.len().min(room);
        self.buf[self.len..self.len + n].copy_from_slice(&s.as_bytes()[..n]);
        self.len += n;
        if n < s.len() {
            Err(fmt::Error)
        } else {
            Ok(())
        }
    }
}
