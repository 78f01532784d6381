//! `inspect`: a model's header, sections and mesh in physical units.

use std::path::Path;

use anyhow::Result;
use fogtemp_core::{Model, OutsidePolicy};
use serde_json::{json, Value};

use super::read_model;
use crate::args::InspectArgs;
use crate::output::hex;

fn inspect_json(path: &Path, blob: &[u8], model: &Model<'_>) -> Result<Value> {
    let mut axes = Vec::new();
    for i in 0..model.axis_count() {
        let axis = model.axis(i).map_err(|e| anyhow::anyhow!("{e}"))?;
        let n = &axis.normalisation;
        let mut kind = Vec::new();
        if axis.poly.is_some() {
            kind.push("poly");
        }
        if axis.mesh.is_some() {
            kind.push("mesh");
        }
        let (mut nodes, mut triangles, mut hull) = (Vec::new(), Vec::new(), Vec::new());
        let mut policy = Value::Null;
        if let Some(mesh) = &axis.mesh {
            policy = json!(match mesh.outside_policy() {
                OutsidePolicy::NearestHull => "nearest_hull",
                OutsidePolicy::Zero => "zero",
            });
            for v in (0..mesh.vertex_count()).filter_map(|k| mesh.vertex(k)) {
                let (t, r) = fogtemp_cal::mesh::to_physical(n, f64::from(v.x), f64::from(v.y));
                let poly = axis.poly.map_or(0.0, |p| p.evaluate(v.x, v.y));
                nodes.push(json!({
                    "temp_c": t, "rate_c_per_min": r,
                    "value_dph": poly + v.value_dph, "mesh_value_dph": v.value_dph,
                    "x": v.x, "y": v.y,
                }));
            }
            for tri in (0..mesh.triangle_count()).filter_map(|k| mesh.triangle(k)) {
                triangles.push(json!(tri.vertices));
            }
            for (a, _) in
                (0..mesh.hull_edge_count()).filter_map(|k| mesh.hull_edge(k)).filter_map(|(t, e)| {
                    let rec = mesh.triangle(t)?;
                    let e = e as usize;
                    Some((rec.vertices[(e + 1) % 3], rec.vertices[(e + 2) % 3]))
                })
            {
                hull.push(a);
            }
        }
        let p = &axis.provenance;
        axes.push(json!({
            "axis": i,
            "kind": kind,
            "features": {
                "window_s": axis.features.window_s, "block_count": axis.features.block_count,
                "min_blocks": axis.features.min_blocks, "max_gap_s": axis.features.max_gap_s,
            },
            "normalisation": {
                "temp_offset_c": n.temp_offset_c, "temp_scale_per_c": n.temp_scale_per_c,
                "rate_offset_c_per_min": n.rate_offset_c_per_min, "rate_scale_per_c_per_min": n.rate_scale_per_c_per_min,
            },
            "outside_policy": policy,
            "provenance": {
                "fit_point_count": p.fit_point_count, "residual_rms_dph": p.residual_rms_dph,
                "residual_max_abs_dph": p.residual_max_abs_dph,
                "temp_min_c": p.temp_min_c, "temp_max_c": p.temp_max_c,
                "rate_min_c_per_min": p.rate_min_c_per_min, "rate_max_c_per_min": p.rate_max_c_per_min,
            },
            "poly": axis.poly.map(|poly| poly.terms().map(|t| json!({
                "temp_power": t.temp_power, "rate_power": t.rate_power, "coefficient_dph": t.coefficient_dph,
            })).collect::<Vec<_>>()),
            "nodes": nodes,
            "triangles": triangles,
            "hull": hull,
        }));
    }
    Ok(json!({
        "model": path.display().to_string(),
        "bytes": blob.len(),
        "format_version": model.format_version(),
        "tool_version": String::from_utf8_lossy(model.tool_version()),
        "input_digest": hex(&model.input_digest()),
        "axes": axes,
    }))
}

pub fn inspect(a: InspectArgs) -> Result<()> {
    let blob = read_model(&a.model)?;
    let model = Model::from_bytes(&blob).map_err(|e| anyhow::anyhow!("{e}"))?;
    let doc = inspect_json(&a.model, &blob, &model)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(());
    }
    println!(
        "{}: fogtemp model, format {}, {} bytes, written by '{}', input digest {}",
        a.model.display(),
        doc["format_version"],
        blob.len(),
        String::from_utf8_lossy(model.tool_version()),
        hex(&model.input_digest())
    );
    for axis in doc["axes"].as_array().into_iter().flatten() {
        println!(
            "axis {}: {} | window {} s in {} blocks, restart after {} s | {} polynomial terms, {} nodes, {} triangles, outside: {} | fit residual RMS {} deg/h over {} points",
            axis["axis"],
            axis["kind"].as_array().map(|k| k.iter().filter_map(|v| v.as_str()).collect::<Vec<_>>().join("+")).unwrap_or_default(),
            axis["features"]["window_s"],
            axis["features"]["block_count"],
            axis["features"]["max_gap_s"],
            axis["poly"].as_array().map_or(0, |p| p.len()),
            axis["nodes"].as_array().map_or(0, |n| n.len()),
            axis["triangles"].as_array().map_or(0, |t| t.len()),
            axis["outside_policy"],
            axis["provenance"]["residual_rms_dph"],
            axis["provenance"]["fit_point_count"],
        );
        println!(
            "  calibrated range: {} .. {} C, {} .. {} C/min",
            axis["provenance"]["temp_min_c"],
            axis["provenance"]["temp_max_c"],
            axis["provenance"]["rate_min_c_per_min"],
            axis["provenance"]["rate_max_c_per_min"]
        );
    }
    Ok(())
}
