//! fogtemp firmware harness for QEMU `mps2-an386` (Cortex-M4F, `thumbv7em-none-eabihf`).
//!
//! What it does, in order:
//! 1. prints the FPU state (CPACR, FPSCR) so a run log shows the FPU is on and
//!    flush-to-zero / default-NaN are off;
//! 2. runs a small f32 self-test whose exact bit results were computed on the
//!    x86_64 host with the same Rust code, and fails the run on any mismatch;
//! 3. parses the embedded model blob with `fogtemp_core::Model::from_bytes`, builds a
//!    `Compensator` for axis 0 and replays every record of the embedded trajectory
//!    through `Compensator::step`, printing the selected outputs as exact f32 bits;
//! 4. exits QEMU through semihosting: status 0 on success, 1 on failure
//!    (a panic also exits with 1, via `panic-semihosting`'s `exit` feature).
//!
//! The embedded data and the expected output are generated on the host by the root
//! test `tests/firmware_fixture.rs`, which runs the host build of the same core over the
//! same trajectory; `.ci/firmware-qemu.sh` compares the two outputs exactly.
//!
//! Output line grammar (one record per line, space separated):
//! * `out <index> <rate bits> <bias bits> <flags>`: record `index` (0-based) compensated;
//!   rate and bias are `f32::to_bits()` as 8 lowercase hex digits, flags 2 hex digits
//!   (`fogtemp_core::Flags`). Printed for record 0, the last record, every
//!   [`PRINT_STRIDE`]-th record and every record whose flags or bias differ from the
//!   previous record's.
//! * `digest <records> <16 hex digits>`: FNV-1a 64 over the outputs of *every* record
//!   (rate bits, bias bits, flags), so unprinted records are compared too.
//! * `done records=<n> printed=<m>`: last line of a successful run.
//! * `fpu ...`, `selftest ...`, `model ...` lines are diagnostics.
//!
//! With the cargo feature `baseline` the compensator is replaced by a pass-through
//! (no `Model::from_bytes`, no `Compensator`): the same harness without the runtime,
//! built only to measure the runtime's flash size by difference (see README).

#![no_std]
#![no_main]

use core::fmt::{self, Write as _};
use core::hint::black_box;

use cortex_m_rt::entry;
use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};
use cortex_m_semihosting::{hio, hprintln};
use fogtemp_core::Output;
use panic_semihosting as _;

/// Model blob, staged by build.rs from `$FOGTEMP_FW_MODEL` (default `data/model.fogm`).
static MODEL_BLOB: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/model.bin"));

/// Trajectory records, staged by build.rs from `$FOGTEMP_FW_TRAJECTORY`
/// (default `data/trajectory.bin`).
static TRAJECTORY: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/trajectory.bin"));

/// Feature-tracker capacity (blocks); the fixture model uses 20.
#[cfg(not(feature = "baseline"))]
const TRACKER_CAPACITY: usize = 32;

/// Every `PRINT_STRIDE`-th record is printed (as in `tests/firmware_fixture.rs`).
const PRINT_STRIDE: usize = 20;

#[entry]
fn main() -> ! {
    hprintln!("fogtemp firmware-qemu: start");
    report_fpu();

    let mut ok = selftest();

    let mut out = HostOut::new();
    match replay(&mut out, MODEL_BLOB, TRAJECTORY) {
        Ok(summary) => {
            out.line(format_args!("digest {} {:016x}", summary.records, summary.digest));
            out.line(format_args!("done records={} printed={}", summary.records, summary.printed));
            out.flush();
        }
        Err(e) => {
            out.flush();
            hprintln!("error replay: {}", e);
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
    let (c0, c1, c2, c3) =
        (black_box(0.75f32), black_box(-0.0125f32), black_box(3.5e-4f32), black_box(-2.0e-6f32));
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
        ("subnormal", black_box(f32::MIN_POSITIVE) * black_box(0.25f32), 0x0020_0000_u32),
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
    time_us: u64,
    /// Raw gyro rate in deg/h.
    gyro_dph: f32,
    /// Sensor temperature in deg C, if one arrived with this sample (NaN in the file).
    temp_c: Option<f32>,
}

impl Record {
    fn decode(b: &[u8; RECORD_LEN]) -> Self {
        let [t0, t1, t2, t3, t4, t5, t6, t7, g0, g1, g2, g3, c0, c1, c2, c3] = *b;
        let temp_c = f32::from_le_bytes([c0, c1, c2, c3]);
        Record {
            time_us: u64::from_le_bytes([t0, t1, t2, t3, t4, t5, t6, t7]),
            gyro_dph: f32::from_le_bytes([g0, g1, g2, g3]),
            temp_c: if temp_c.is_nan() { None } else { Some(temp_c) },
        }
    }
}

/// Why a replay could not run.
enum ReplayError {
    /// Trajectory length is not a multiple of [`RECORD_LEN`].
    TrajectoryLength(usize),
    /// The core rejected the model (or the axis / tracker capacity).
    #[cfg(not(feature = "baseline"))]
    Model(fogtemp_core::Error),
}

impl fmt::Display for ReplayError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReplayError::TrajectoryLength(n) => {
                write!(f, "trajectory is {} bytes, not a multiple of {}", n, RECORD_LEN)
            }
            #[cfg(not(feature = "baseline"))]
            ReplayError::Model(e) => write!(f, "model: {}", e),
        }
    }
}

// ---------------------------------------------------------------------------
// The runtime under test (and its pass-through stand-in for size measurement)
// ---------------------------------------------------------------------------

/// `fogtemp_core`: validate the blob, then one `Compensator` for axis 0.
#[cfg(not(feature = "baseline"))]
mod runtime {
    use super::{ReplayError, TRACKER_CAPACITY};
    use cortex_m_semihosting::hprintln;
    use fogtemp_core::{Compensator, Model, Output};

    pub struct Runtime<'a>(Compensator<'a, TRACKER_CAPACITY>);

    impl<'a> Runtime<'a> {
        pub fn new(blob: &'a [u8]) -> Result<Self, ReplayError> {
            let model = Model::from_bytes(blob).map_err(ReplayError::Model)?;
            let comp = Compensator::new(&model, 0).map_err(ReplayError::Model)?;
            let axis = comp.axis();
            let (poly_terms, vertices, triangles, hull) = (
                axis.poly.map_or(0, |p| p.len()),
                axis.mesh.map_or(0, |m| m.vertex_count()),
                axis.mesh.map_or(0, |m| m.triangle_count()),
                axis.mesh.map_or(0, |m| m.hull_edge_count()),
            );
            hprintln!(
                "model bytes={} axes={} poly_terms={} vertices={} triangles={} hull_edges={} blocks={} state_bytes={}",
                blob.len(),
                model.axis_count(),
                poly_terms,
                vertices,
                triangles,
                hull,
                axis.features.block_count,
                core::mem::size_of::<Compensator<'_, TRACKER_CAPACITY>>(),
            );
            Ok(Runtime(comp))
        }

        #[inline(always)]
        pub fn step(&mut self, time_us: u64, gyro_dph: f32, temp_c: Option<f32>) -> Output {
            self.0.step(time_us, gyro_dph, temp_c)
        }
    }
}

/// Pass-through with the same interface: rate = gyro, bias = temperature (or 0), no
/// model. Only for measuring the harness without the runtime; its output is not checked.
#[cfg(feature = "baseline")]
mod runtime {
    use super::ReplayError;
    use fogtemp_core::{Flags, Output};

    pub struct Runtime;

    impl Runtime {
        pub fn new(blob: &[u8]) -> Result<Self, ReplayError> {
            cortex_m_semihosting::hprintln!("model bytes={} (baseline: not parsed)", blob.len());
            Ok(Runtime)
        }

        #[inline(always)]
        pub fn step(&mut self, time_us: u64, gyro_dph: f32, temp_c: Option<f32>) -> Output {
            Output { rate_dph: gyro_dph, bias_dph: temp_c.unwrap_or(0.0), flags: Flags((time_us & 1) as u8) }
        }
    }
}

// ---------------------------------------------------------------------------
// Replay
// ---------------------------------------------------------------------------

/// What a successful replay reports.
struct Summary {
    records: usize,
    printed: usize,
    digest: u64,
}

/// FNV-1a 64, fed with every output (same as the host fixture).
struct Fnv1a(u64);

impl Fnv1a {
    fn new() -> Self {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }

    fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    fn output(&mut self, o: &Output) {
        self.bytes(&o.rate_dph.to_bits().to_le_bytes());
        self.bytes(&o.bias_dph.to_bits().to_le_bytes());
        self.bytes(&[o.flags.0]);
    }
}

/// Replays every record through the runtime and prints the selected outputs.
fn replay(out: &mut HostOut, model: &[u8], trajectory: &[u8]) -> Result<Summary, ReplayError> {
    if trajectory.len() % RECORD_LEN != 0 {
        return Err(ReplayError::TrajectoryLength(trajectory.len()));
    }
    let mut runtime = runtime::Runtime::new(model)?;
    let records = trajectory.len() / RECORD_LEN;
    let mut digest = Fnv1a::new();
    let mut previous: Option<(u32, u8)> = None;
    let mut printed = 0;
    for (index, chunk) in trajectory.chunks_exact(RECORD_LEN).enumerate() {
        let mut buf = [0u8; RECORD_LEN];
        buf.copy_from_slice(chunk);
        let rec = Record::decode(&buf);

        let o = runtime.step(rec.time_us, rec.gyro_dph, rec.temp_c);

        digest.output(&o);
        let now = (o.bias_dph.to_bits(), o.flags.0);
        if previous != Some(now) || index % PRINT_STRIDE == 0 || index + 1 == records {
            out.line(format_args!(
                "out {} {:08x} {:08x} {:02x}",
                index,
                o.rate_dph.to_bits(),
                o.bias_dph.to_bits(),
                o.flags.0
            ));
            printed += 1;
        }
        previous = Some(now);
    }
    Ok(Summary { records, printed, digest: digest.0 })
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
        HostOut { stream: hio::hstdout().ok(), buf: [0; 1024], len: 0 }
    }

    /// Append one formatted line plus `\n`.
    fn line(&mut self, args: fmt::Arguments<'_>) {
        if self.buf.len() - self.len < MAX_LINE + 1 {
            self.flush();
        }
        let start = self.len;
        let mut w = SliceWriter { buf: &mut self.buf[start..start + MAX_LINE], len: 0 };
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
