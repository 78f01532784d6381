//! `inspect`: a model's header, sections and mesh in physical units.

use anyhow::Result;
use fogtemp_cal::documents::ModelDocument;

use super::{json_text, print_json, read_model};
use crate::args::InspectArgs;

/// The `inspect` command.
pub fn inspect(a: InspectArgs) -> Result<()> {
    let Some(model) = a.model.or(a.model_flag) else {
        anyhow::bail!("give the model file: fogtemp-cal inspect MODEL (or --model MODEL)");
    };
    let blob = read_model(&model)?;
    let doc = ModelDocument::new(&model, &blob).map_err(|e| anyhow::anyhow!("{e}"))?;
    if a.json {
        return print_json(&doc);
    }
    println!(
        "{}: fogtemp model, format {}, {} bytes, written by '{}', input digest {}",
        model.display(),
        doc.format_version,
        doc.bytes,
        doc.tool_version,
        doc.input_digest
    );
    match &doc.log_time {
        Some(time) => println!("log time: {}", time.description),
        None if doc.format_version < 5 => println!("log time: not recorded (format {})", doc.format_version),
        None => println!("log time: not recorded"),
    }
    match &doc.log_reading {
        Some(r) => println!(
            "log reading: decimal {}; {} calibration log digest{} (validate names a log among them)",
            r.decimal_mark,
            r.log_digests.len(),
            if r.log_digests.len() == 1 { "" } else { "s" }
        ),
        None => println!("log reading: not recorded (format {})", doc.format_version),
    }
    if let Some(shape) = &doc.log_shape {
        println!(
            "log shape: {} (validate and compensate read logs so unless told otherwise)",
            shape.description
        );
    }
    match doc.input_rates_subtracted {
        Some(true) => println!("input rates: taken off each calibration run's gyro before the fit (the model is the bias alone)"),
        Some(false) => println!(
            "input rates: given by the run metadata but left in (several gyro columns): the model holds its calibration runs' rate as bias"
        ),
        None => println!("input rates: not recorded (fitted without run metadata, or before format 8)"),
    }
    // The stored values are f32: printed to the digits they hold (every one is in --json).
    let number = |v: f64, digits: usize| if v.is_finite() { format!("{v:.digits$}") } else { "null".into() };
    for axis in &doc.axes {
        let mesh_outside =
            axis.outside_policy.map_or_else(|| "no mesh".to_string(), |p| format!("mesh outside: {p}"));
        println!(
            "axis {}: {} | window {} s in {} blocks, restart after {} s | {} polynomial terms, {} nodes, {} triangles, {} | fit residual RMS {} deg/h over {} points",
            axis.axis,
            kind_text(axis),
            json_text(&axis.features.window_s),
            axis.features.block_count,
            json_text(&axis.features.max_gap_s),
            axis.poly.as_ref().map_or(0, Vec::len),
            axis.nodes.len(),
            axis.triangles.len(),
            mesh_outside,
            number(axis.provenance.residual_rms_dph, 5),
            axis.provenance.fit_point_count,
        );
        println!(
            "  calibrated range: {} .. {} C, {} .. {} C/min; feature tracker capacity needed: {} blocks",
            number(axis.provenance.temp_min_c, 2),
            number(axis.provenance.temp_max_c, 2),
            number(axis.provenance.rate_min_c_per_min, 4),
            number(axis.provenance.rate_max_c_per_min, 4),
            axis.features.blocks_needed
        );
        if let Some(terms) = axis.poly.as_ref().filter(|t| !t.is_empty()) {
            // The terms themselves, as `--help` promises (review15: only their count was shown).
            let n = &axis.normalisation;
            let listed: Vec<String> = terms
                .iter()
                .map(|t| match (t.temp_power, t.rate_power) {
                    (0, 0) => number(t.coefficient_dph, 6),
                    (a, b) => {
                        format!("{} {}", number(t.coefficient_dph, 6), fogtemp_cal::poly_fit::monomial(a, b))
                    }
                })
                .collect();
            println!(
                "  polynomial, deg/h: {} (x = (T {} C) x {} /C, y = (dT/dt {} C/min) x {} min/C)",
                listed.join(" + ").replace("+ -", "- "),
                fogtemp_cal::numbers::minus_text(n.temp_offset_c, 4),
                number(n.temp_scale_per_c, 6),
                fogtemp_cal::numbers::minus_text(n.rate_offset_c_per_min, 6),
                number(n.rate_scale_per_c_per_min, 6)
            );
        }
        if let Some(outside) = axis.poly_outside {
            println!(
                "  polynomial outside the calibrated region ({} vertices): {outside}",
                axis.region_vertex_count
            );
        }
        match (&axis.gyro_column, &axis.temp_column) {
            (None, None) if doc.format_version < 4 => {
                println!("  log columns: not recorded (format {}): matched by position", doc.format_version)
            }
            (gyro, temp) => {
                let name = |n: &Option<String>| {
                    n.as_ref().map_or_else(|| "not recorded".into(), |n| format!("'{n}'"))
                };
                println!("  fitted on the log columns: gyro {}, temperature {}", name(gyro), name(temp));
                if let (Some(g), Some(t), Some(o)) =
                    (axis.gyro_dph_per_unit, axis.temp_c_per_unit, axis.temp_offset_c)
                {
                    let sign = if o < 0.0 { '-' } else { '+' };
                    println!("  read as: deg/h = gyro x {g}; deg C = temperature x {t} {sign} {}", o.abs());
                }
            }
        }
        if let Some(selection) = &axis.provenance.selection {
            println!("  method: {selection}");
        }
    }
    Ok(())
}

/// The axis's kind, a polynomial without a rate term said to be in T alone (a `cubic-t`, or a
/// stepwise fit that admitted no rate term: review21 F7, "poly" read as the (T, dT/dt) fit).
fn kind_text(axis: &fogtemp_cal::documents::ModelAxisDocument) -> String {
    let t_alone = axis.poly.as_ref().is_some_and(|terms| terms.iter().all(|t| t.rate_power == 0));
    axis.kind
        .iter()
        .map(|&k| if k == "poly" && t_alone { "poly in T alone" } else { k })
        .collect::<Vec<_>>()
        .join("+")
}
