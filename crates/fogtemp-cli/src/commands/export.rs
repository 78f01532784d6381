//! `export`: the model blob as a Rust or C source array for firmware.

use anyhow::{bail, Result};

use super::read_model;
use crate::args::{ExportArgs, ExportFormat};
use crate::output::{check_output_file, refuse_overwriting_inputs, stage, write_atomic};

pub fn export(a: ExportArgs) -> Result<()> {
    // `-` is stdout, as for compensate; a C export is two files (review22 F6: `--out -` made
    // files named `-` and `-.h`).
    let to_stdout = a.out.as_os_str() == "-";
    if to_stdout && a.format == ExportFormat::C {
        bail!("--out -: --format c writes a source and a header beside it, so it needs a path (e.g. --out model.c); --out - (stdout) is for --format rust");
    }
    if !to_stdout {
        check_output_file(&a.out)?;
    }
    refuse_overwriting_inputs(&a.out, &[&a.model])?;
    if a.format == ExportFormat::C {
        // A device or a pipe has no folder of its own for the header (review27a 1: `--out
        // /dev/full` made /dev/full.h).
        if let fogtemp_cal::output::Destination::InPlace(_) = fogtemp_cal::output::destination(&a.out)? {
            bail!(
                "--out {}: is a device or a pipe; --format c writes a source and a header beside it, so it needs the path of a .c file (e.g. --out model.c)",
                a.out.display()
            );
        }
        if a.out.with_extension("h") == a.out {
            bail!(
                "--out {}: for --format c, --out names the C source, and its header is written beside it with the extension .h; give a .c path (e.g. {})",
                a.out.display(),
                a.out.with_extension("c").display()
            );
        }
        check_output_file(&header_path_of(&a.out)?)?;
        refuse_overwriting_inputs(&header_path_of(&a.out)?, &[&a.model])?;
    }
    let blob = read_model(&a.model)?;
    let name = &a.name;
    if name.is_empty()
        || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        || name.starts_with(|c: char| c.is_ascii_digit())
    {
        bail!("--name '{name}' is not a valid identifier");
    }
    let keywords: &[&str] = match a.format {
        ExportFormat::Rust => &RUST_KEYWORDS,
        ExportFormat::C => &C_KEYWORDS,
    };
    if keywords.contains(&name.as_str()) {
        bail!("--name '{name}' is a keyword of the target language; choose another name (the default is FOGTEMP_MODEL)");
    }
    if a.format == ExportFormat::C && name.starts_with("fogtemp_") {
        bail!("--name '{name}': fogtemp.h declares its types and functions as fogtemp_*, so the array could clash with one (fogtemp_model is a type); choose another name (the default is FOGTEMP_MODEL)");
    }
    let upper = name.to_ascii_uppercase();
    let bytes_lines = |per_line: usize| -> String {
        blob.chunks(per_line)
            .map(|c| format!("    {}", c.iter().map(|b| format!("0x{b:02x},")).collect::<Vec<_>>().join(" ")))
            .collect::<Vec<_>>()
            .join("\n")
    };
    let source = a.model.display().to_string();
    // The tracker capacity the firmware's Compensator must have: a constant beside the bytes,
    // so a firmware built with less fails at compile time (e.g. a static assertion).
    let model = fogtemp_core::Model::from_bytes(&blob).map_err(|e| anyhow::anyhow!("{e}"))?;
    let capacity = (0..model.axis_count())
        .filter_map(|i| model.axis(i).ok())
        .map(|x| x.blocks_needed())
        .max()
        .unwrap_or(0);
    let units = unit_constants(&model, &upper);
    // The names the export declares must not be fogtemp.h's own (review23a F7:
    // --name FOGTEMP_STATUS_OK compiled into a redeclaration).
    if a.format == ExportFormat::C {
        let fixed = [
            name.clone(),
            format!("{upper}_LEN"),
            format!("{upper}_CAPACITY"),
            format!("{upper}_FOGTEMP_EXPORT_H"),
        ];
        if let Some(clash) = fixed.iter().chain(units.iter().map(|(n, _, _)| n)).find(|d| header_declares(d))
        {
            bail!("--name '{name}': fogtemp.h already declares {clash}, which the export would declare again; choose another name (the default is FOGTEMP_MODEL)");
        }
    }
    match a.format {
        ExportFormat::Rust if to_stdout => {
            let mut out = std::io::stdout().lock();
            let written =
                write_rust(&mut out, &source, &blob, (name, &upper), capacity, &units, &bytes_lines(16))
                    .and_then(|()| std::io::Write::flush(&mut out));
            // A reader that closed the pipe (`| head`) has what it wanted: a quiet end, as
            // every other output to stdout (review25a 6).
            return match written {
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => std::process::exit(0),
                other => Ok(other?),
            };
        }
        ExportFormat::Rust => write_atomic(&a.out, |w| {
            write_rust(w, &source, &blob, (name, &upper), capacity, &units, &bytes_lines(16))?;
            Ok(())
        }),
        ExportFormat::C => {
            let header_path = header_path_of(&a.out)?;
            let header_name = header_path
                .file_name()
                .map_or_else(|| "model.h".into(), |n| n.to_string_lossy().into_owned());
            // A suffix no fogtemp header uses: `--name fogtemp` gave FOGTEMP_H, fogtemp.h's own
            // guard, and the second include vanished (review22 F6).
            let guard = format!("{upper}_FOGTEMP_EXPORT_H");
            // Both files are written before either is moved into place, the source first:
            // an unusable --out leaves no header behind.
            let header = stage(&header_path, |w| {
                writeln!(w, "/* fogtemp model exported from {source}. Generated by fogtemp-cal export; do not edit. */")?;
                writeln!(w, "#ifndef {guard}\n#define {guard}\n#include <stdint.h>\n")?;
                writeln!(w, "#define {upper}_LEN {}u", blob.len())?;
                writeln!(w, "/* feature tracker capacity (blocks) the model needs: the blocks array of fogtemp_state_init */")?;
                writeln!(w, "#define {upper}_CAPACITY {capacity}u")?;
                if !units.is_empty() {
                    writeln!(w, "/* {UNITS_NOTE} */")?;
                }
                for (constant, value, what) in &units {
                    // A float literal: `raw * CONSTANT` stays single precision (review33a F4: a
                    // double constant put soft-float double arithmetic in every sample on an M4F).
                    writeln!(w, "#define {constant} {value:?}f /* {what} */")?;
                }
                writeln!(w, "extern const uint8_t {name}[{}];\n\n#endif", blob.len())?;
                Ok(())
            })?;
            let source_file = stage(&a.out, |w| {
                writeln!(w, "/* fogtemp model exported from {source} ({} bytes). Generated by fogtemp-cal export; do not edit. */", blob.len())?;
                writeln!(w, "#include \"{header_name}\"\n")?;
                writeln!(w, "const uint8_t {name}[{}] = {{\n{}\n}};", blob.len(), bytes_lines(16))?;
                Ok(())
            })?;
            source_file.commit()?;
            header.commit()?;
            println!("wrote {} and {}", a.out.display(), header_path.display());
            return Ok(());
        }
    }?;
    println!("wrote {}", a.out.display());
    Ok(())
}

/// What the unit constants are for, above them in the export.
const UNITS_NOTE: &str = "the sensor's units as the model was fitted (fogtemp-cal inspect: \"read as\"): \
     convert before each step: gyro_dph = gyro * GYRO_DPH_PER_UNIT, temp_c = temperature * TEMP_C_PER_UNIT + TEMP_OFFSET_C";

/// The conversions each axis was fitted with, as constants `(name, value, what)`: `UPPER_` or,
/// with several axes, `UPPER_AXIS<i>_` then `GYRO_DPH_PER_UNIT`, `TEMP_C_PER_UNIT`,
/// `TEMP_OFFSET_C`. None for a model that records no columns (before format 4): its
/// inputs are deg/h and deg C. The firmware feeds the core deg/h and deg C, so a model fitted
/// on raw counts or rad/s needs these (review23a F2: psim-tvc's rad/s x 0.5 and counts were
/// said nowhere a C build could read).
fn unit_constants(model: &fogtemp_core::Model<'_>, upper: &str) -> Vec<(String, f64, &'static str)> {
    let axes = model.axis_count();
    (0..axes)
        .filter_map(|i| fogtemp_cal::blob::ColumnNames::of(model, i).map(|c| (i, c)))
        .flat_map(|(i, c)| {
            let prefix = if axes == 1 { upper.to_string() } else { format!("{upper}_AXIS{i}") };
            [
                (
                    format!("{prefix}_GYRO_DPH_PER_UNIT"),
                    c.gyro_dph_per_unit,
                    "deg/h per unit of the gyro column",
                ),
                (
                    format!("{prefix}_TEMP_C_PER_UNIT"),
                    c.temp_c_per_unit,
                    "deg C per unit of the temperature column",
                ),
                (format!("{prefix}_TEMP_OFFSET_C"), c.temp_offset_c, "deg C added after the scale"),
            ]
        })
        .collect()
}

/// The Rust source of an export: the blob as a static array, the tracker capacity it needs
/// and the units it was fitted in.
fn write_rust(
    w: &mut (impl std::io::Write + ?Sized),
    source: &str,
    blob: &[u8],
    (name, upper): (&str, &str),
    capacity: usize,
    units: &[(String, f64, &str)],
    bytes: &str,
) -> std::io::Result<()> {
    writeln!(
        w,
        "// fogtemp model exported from {source} ({} bytes). Generated by fogtemp-cal export; do not edit.",
        blob.len()
    )?;
    writeln!(
        w,
        "/// The fogtemp model blob ({} bytes): `fogtemp_core::Model::from_bytes(&{name})`.",
        blob.len()
    )?;
    writeln!(w, "pub static {name}: [u8; {}] = [\n{bytes}\n];", blob.len())?;
    writeln!(w, "/// Feature tracker capacity (blocks) the model needs: `Compensator::<N>` with N >= this.")?;
    writeln!(w, "pub const {upper}_CAPACITY: usize = {capacity};")?;
    if !units.is_empty() {
        writeln!(w, "// {UNITS_NOTE}")?;
    }
    for (constant, value, what) in units {
        writeln!(w, "/// {what}\npub const {constant}: f64 = {value:?};")?;
    }
    Ok(())
}

/// Rust's strict and reserved keywords (2021 edition): not usable as a static's name.
const RUST_KEYWORDS: [&str; 51] = [
    "as", "break", "const", "continue", "crate", "else", "enum", "extern", "false", "fn", "for", "if",
    "impl", "in", "let", "loop", "match", "mod", "move", "mut", "pub", "ref", "return", "self", "Self",
    "static", "struct", "super", "trait", "true", "type", "unsafe", "use", "where", "while", "async",
    "await", "dyn", "abstract", "become", "box", "do", "final", "macro", "override", "priv", "typeof",
    "unsized", "virtual", "yield", "try",
];

/// C11's keywords: not usable as an array's name.
const C_KEYWORDS: [&str; 44] = [
    "auto",
    "break",
    "case",
    "char",
    "const",
    "continue",
    "default",
    "do",
    "double",
    "else",
    "enum",
    "extern",
    "float",
    "for",
    "goto",
    "if",
    "inline",
    "int",
    "long",
    "register",
    "restrict",
    "return",
    "short",
    "signed",
    "sizeof",
    "static",
    "struct",
    "switch",
    "typedef",
    "union",
    "unsigned",
    "void",
    "volatile",
    "while",
    "_Alignas",
    "_Alignof",
    "_Atomic",
    "_Bool",
    "_Complex",
    "_Generic",
    "_Imaginary",
    "_Noreturn",
    "_Static_assert",
    "_Thread_local",
];

/// The C header every exported model is compiled beside.
const FOGTEMP_H: &str = include_str!("../../../fogtemp-ffi/include/fogtemp.h");

/// `identifier` occurs as a whole identifier in fogtemp.h's code (its comments left out:
/// they name "fogtemp" itself).
fn header_declares(identifier: &str) -> bool {
    without_comments(FOGTEMP_H)
        .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .any(|word| word == identifier)
}

/// C text without its `//` and `/* */` comments (the header holds no string literals).
fn without_comments(text: &str) -> String {
    let mut code = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(at) = rest.find("//").into_iter().chain(rest.find("/*")).min() {
        code.push_str(&rest[..at]);
        code.push(' ');
        let end = if rest[at..].starts_with("//") {
            rest[at..].find('\n')
        } else {
            rest[at..].find("*/").map(|e| e + 2)
        };
        rest = end.map_or("", |e| &rest[at + e..]);
    }
    code.push_str(rest);
    code
}

/// The header beside the C source `out` writes: beside the file a link names, so that its
/// `#include` finds it (review28a 7: through a link into another folder, the source went
/// there and the header beside the link).
fn header_path_of(out: &std::path::Path) -> Result<std::path::PathBuf> {
    Ok(fogtemp_cal::output::destination(out)?.path().with_extension("h"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn comments_are_not_declarations() {
        assert_eq!(without_comments("a // b\nc /* d\n e */ f"), "a  \nc   f");
        assert!(header_declares("FOGTEMP_STATUS_OK") && header_declares("fogtemp_step"));
        assert!(!header_declares("fogtemp") && !header_declares("FOGTEMP_MODEL"));
    }
}
