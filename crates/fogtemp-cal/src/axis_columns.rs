//! Which log columns feed which model axis when a model is replayed (`validate`,
//! `compensate`), and in which units: the columns and units the model records (format
//! version 4) unless others are named, and named columns checked against them, so a swapped
//! pair of gyro columns is refused instead of compensated with the other axis's model.

use fogtemp_core::Model;

use crate::blob::{ColumnNames, LogShapeRecord, LogTimeRecord};
use crate::ingest::{DecimalMark, Delimiter, LogFormat, RateUnit};

/// The columns chosen for a model, and what the user is told about them.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ChosenColumns {
    /// Gyro columns, axis k reading the k-th.
    pub gyro: Vec<String>,
    /// Temperature columns: one shared, or one per gyro column.
    pub temp: Vec<String>,
    /// Columns named that differ from the ones the model was fitted on (used as given).
    pub notes: Vec<String>,
    /// The gyro columns were taken from the model (none were named).
    pub gyro_from_model: bool,
}

/// A named column that the model records for another axis: the log is read with the axes
/// swapped. `setting` names the option (`--gyro-column`, `gyro_column=`).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "{model}: {setting} gives '{given}' for axis {axis}, but the model's axis {axis} was fitted on '{fitted}' \
     and its axis {other_axis} on '{given}': the columns would be compensated with another axis's model. \
     Name them in the model's order ({order}), or leave {setting} out to use the columns the model records"
)]
pub struct SwappedColumn {
    /// The model file.
    pub model: String,
    /// The option that named the column.
    pub setting: String,
    /// The axis the column was given for.
    pub axis: usize,
    /// The column given for it.
    pub given: String,
    /// The column the model fitted that axis on.
    pub fitted: String,
    /// The axis the model fitted the given column on.
    pub other_axis: usize,
    /// The model's columns in order, as the option takes them.
    pub order: String,
}

/// What the user named for a replay (empty, `false`: not named).
#[derive(Clone, Copy, Debug)]
pub struct Named<'a> {
    /// `--gyro-column` values.
    pub gyro_columns: &'a [String],
    /// `--temp-column` values.
    pub temp_columns: &'a [String],
    /// `--gyro-unit` or `--gyro-scale` given.
    pub gyro_units: bool,
    /// `--temp-scale` or `--temp-offset` given.
    pub temp_units: bool,
    /// Which of `--time-column`, `--time-unit`, `--sample-rate-hz`, `--date-column` were given.
    pub time: TimeNamed,
    /// `--decimal-mark` given.
    pub decimal_mark: bool,
    /// Which of `--skip-lines`, `--delimiter`, `--comment`, `--columns` were given.
    pub shape: ShapeNamed,
}

/// Which log-shape settings the user named for a replay; the others come from the model's
/// log-shape record ([`choose_shape`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ShapeNamed {
    /// `--skip-lines` given.
    pub skip_lines: bool,
    /// `--delimiter` given.
    pub delimiter: bool,
    /// `--comment` given.
    pub comment: bool,
    /// `--columns` given.
    pub columns: bool,
}

impl ShapeNamed {
    /// Every shape setting named.
    pub const ALL: Self = Self { skip_lines: true, delimiter: true, comment: true, columns: true };
}

/// Which time settings the user named for a replay; the others come from the model's
/// log-time record ([`choose_time`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TimeNamed {
    /// `--time-column` given.
    pub column: bool,
    /// `--time-unit` given.
    pub unit: bool,
    /// `--sample-rate-hz` given.
    pub sample_rate: bool,
    /// `--date-column` given.
    pub date: bool,
}

impl TimeNamed {
    /// Every time setting named.
    pub const ALL: Self = Self { column: true, unit: true, sample_rate: true, date: true };

    /// Whether any time setting was named.
    pub fn any(self) -> bool {
        self.column || self.unit || self.sample_rate || self.date
    }
}

impl<'a> Named<'a> {
    /// Everything `format` says, as if named (a compared model is checked against the
    /// columns and units chosen for the first).
    pub fn all_of(format: &'a LogFormat) -> Self {
        Self {
            gyro_columns: &format.gyro_columns,
            temp_columns: &format.temp_columns,
            gyro_units: true,
            temp_units: true,
            time: TimeNamed::ALL,
            decimal_mark: true,
            shape: ShapeNamed::ALL,
        }
    }
}

/// The names of the options in the messages: gyro columns, temperature columns, gyro units,
/// temperature units, time, decimal mark, log shape.
pub type OptionNames<'a> = [&'a str; 7];
/// The command line's options.
pub const CLI_OPTIONS: OptionNames<'static> = [
    "--gyro-column",
    "--temp-column",
    "--gyro-unit/--gyro-scale",
    "--temp-scale/--temp-offset",
    "--time-column/--time-unit/--sample-rate-hz/--date-column",
    "--decimal-mark",
    "--skip-lines/--delimiter/--comment/--columns",
];
/// Python's keywords.
pub const PYTHON_OPTIONS: OptionNames<'static> = [
    "gyro_column=",
    "temp_column=",
    "gyro_unit=/gyro_scale=",
    "temp_scale=/temp_offset=",
    "time_column=/time_unit=/sample_rate_hz=/date_column=",
    "decimal_mark=",
    "skip_lines=/delimiter=/comment=/columns=",
];

/// [`choose`] and [`choose_units`] together: `format` (what was named, defaults elsewhere)
/// becomes what replaying `model` reads, columns and units. The notes of both are returned in
/// [`ChosenColumns::notes`].
///
/// # Errors
/// As [`choose`].
pub fn choose_for_replay(
    model: &Model<'_>,
    model_name: &str,
    format: &mut LogFormat,
    named: Named<'_>,
    [gyro_column, temp_column, gyro_units, temp_units, time, decimal_mark, shape]: OptionNames<'_>,
) -> Result<ChosenColumns, Box<SwappedColumn>> {
    let mut chosen =
        choose(model, model_name, (named.gyro_columns, named.temp_columns), (gyro_column, temp_column))?;
    let units_named = (named.gyro_units, named.temp_units);
    let unit_notes = choose_units(model, model_name, format, units_named, (gyro_units, temp_units));
    chosen.notes.extend(unit_notes);
    chosen.notes.extend(choose_time(model, model_name, format, named.time, time));
    chosen.notes.extend(choose_decimal_mark(model, model_name, format, named.decimal_mark, decimal_mark));
    chosen.notes.extend(choose_shape(model, model_name, format, named.shape, shape));
    format.gyro_columns.clone_from(&chosen.gyro);
    format.temp_columns.clone_from(&chosen.temp);
    Ok(chosen)
}

/// How to read the logs' numbers for `model`: with the decimal mark it records (format
/// version 6) unless one is `named`, with a note when that is a comma, or when the named one
/// differs (`option` names the setting). `format` is set to what is read.
pub fn choose_decimal_mark(
    model: &Model<'_>,
    model_name: &str,
    format: &mut LogFormat,
    named: bool,
    option: &str,
) -> Option<String> {
    let recorded = if model.log_reading()?.decimal_comma { DecimalMark::Comma } else { DecimalMark::Point };
    let word = |mark: DecimalMark| if mark == DecimalMark::Comma { "comma" } else { "point" };
    if !named {
        format.decimal_mark = recorded;
        return (recorded == DecimalMark::Comma).then(|| {
            format!("the logs' numbers are read with a decimal comma, as {model_name} records of its fit")
        });
    }
    (format.decimal_mark != recorded).then(|| {
        format!(
            "{model_name} was fitted on logs with a decimal {}; these are read with a decimal {}, as {option} says",
            word(recorded),
            word(format.decimal_mark)
        )
    })
}

/// How the logs are shaped for `model`: each of the lines skipped, the delimiter, the comment
/// prefix and the headerless column names as the model records them (format version 7) unless
/// `named`, with a note saying what was taken when it is not the default, and one when what is
/// read differs from the record (`option` names the settings). `format` is set to what is
/// read; the notes are returned. A model that records no shape leaves `format` as it is.
pub fn choose_shape(
    model: &Model<'_>,
    model_name: &str,
    format: &mut LogFormat,
    named: ShapeNamed,
    option: &str,
) -> Vec<String> {
    let recorded = LogShapeRecord::of(model);
    let mut read = LogShapeRecord::of_format(format);
    if !named.skip_lines {
        read.skip_lines = recorded.skip_lines;
    }
    if !named.delimiter {
        read.delimiter = recorded.delimiter;
    }
    if !named.comment {
        read.comment.clone_from(&recorded.comment);
    }
    if !named.columns {
        read.column_names.clone_from(&recorded.column_names);
    }
    read.apply_to(format);
    let mut notes = Vec::new();
    let taken = describe_shape(&recorded, |field| match field {
        ShapeField::SkipLines => !named.skip_lines,
        ShapeField::Delimiter => !named.delimiter,
        ShapeField::Comment => !named.comment,
        ShapeField::Columns => !named.columns,
    });
    if !taken.is_empty() {
        notes.push(format!(
            "the logs are read as {model_name} records of its fit's logs: {}",
            taken.join("; ")
        ));
    }
    if recorded.is_recorded() && read != recorded {
        notes.push(format!(
            "{model_name} was fitted on logs shaped otherwise ({}); {option} give {}: used as given (for logs \
             from the same logger, leave {option} out)",
            shape_in_full(&recorded),
            shape_in_full(&read)
        ));
    }
    notes
}

/// What `shape` differs from the default in, in words ("the default shape" for none).
pub fn shape_in_words(shape: &LogShapeRecord) -> String {
    let words = describe_shape(shape, |_| true);
    if words.is_empty() {
        "the default shape".to_string()
    } else {
        words.join("; ")
    }
}

/// Every setting of `shape` in words, defaults included ("no line skipped; the delimiter
/// detected; comment lines start with '#'; a header row"), for the shape a log was read in.
pub fn shape_in_full(shape: &LogShapeRecord) -> String {
    shape_settings(shape).map(|(_, words)| words).join("; ")
}

/// The log-shape settings, for [`describe_shape`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ShapeField {
    SkipLines,
    Delimiter,
    Comment,
    Columns,
}

/// Each setting of `shape` in words.
fn shape_settings(shape: &LogShapeRecord) -> [(ShapeField, String); 4] {
    let lines = match shape.skip_lines {
        0 => "no line skipped".to_string(),
        1 => "1 line skipped at the start".to_string(),
        n => format!("{n} lines skipped at the start"),
    };
    let delimiter = match shape.delimiter {
        Delimiter::Auto => "the delimiter detected".to_string(),
        Delimiter::Byte(b'\t') => "fields separated by tabs".to_string(),
        Delimiter::Byte(b) => format!("fields separated by '{}'", char::from(b)),
        Delimiter::Whitespace => "fields separated by spaces or tabs".to_string(),
    };
    let comment = match &shape.comment {
        Some(prefix) => format!("comment lines start with '{prefix}'"),
        None => "no comment lines".to_string(),
    };
    let header = if shape.column_names.is_empty() {
        "a header row".to_string()
    } else {
        format!("no header row, columns {}", shape.column_names.join(","))
    };
    [
        (ShapeField::SkipLines, lines),
        (ShapeField::Delimiter, delimiter),
        (ShapeField::Comment, comment),
        (ShapeField::Columns, header),
    ]
}

/// The settings of `shape` that differ from the default and that `include` selects, in words.
fn describe_shape(shape: &LogShapeRecord, include: impl Fn(ShapeField) -> bool) -> Vec<String> {
    let default = LogShapeRecord::default();
    let differs = |field: ShapeField| match field {
        ShapeField::SkipLines => shape.skip_lines != default.skip_lines,
        ShapeField::Delimiter => shape.delimiter != default.delimiter,
        ShapeField::Comment => shape.comment != default.comment,
        ShapeField::Columns => shape.column_names != default.column_names,
    };
    shape_settings(shape)
        .into_iter()
        .filter(|(field, _)| include(*field) && differs(*field))
        .map(|(_, words)| words)
        .collect()
}

/// How to read the logs' time for `model`: as the model records it (format version 5) for
/// every setting not `named`, with a note when what is read that way is not the default
/// `time_s` in seconds; as named otherwise, with a note when the result differs from the
/// record (`option` names the settings). A named sample rate replaces the record's time
/// column; a named time column is read in the recorded unit (and with the recorded date
/// column) unless those are named too. `format` is set to what is read; the notes are
/// returned.
pub fn choose_time(
    model: &Model<'_>,
    model_name: &str,
    format: &mut LogFormat,
    named: TimeNamed,
    option: &str,
) -> Vec<String> {
    let recorded = LogTimeRecord::of(model);
    if !recorded.is_recorded() {
        return Vec::new();
    }
    if !named.any() {
        format.set_log_time(&recorded);
        format.sample_rate_from_model = format.sample_rate_hz.is_some();
        if recorded == LogFormat::default().log_time() {
            return Vec::new();
        }
        return vec![format!(
            "the logs' time is read as {model_name} records it: {}",
            describe_time(&recorded)
        )];
    }
    let mut notes = Vec::new();
    if let Some(inherited) = inherit_time(&recorded, format, named) {
        notes.push(format!("{inherited}, as {model_name} records"));
    }
    let given = format.log_time();
    if given != recorded {
        notes.push(format!(
            "{model_name} was fitted on logs whose time is {}; {option} give {}: used as given (for logs from the same logger, leave {option} out)",
            describe_time(&recorded),
            describe_time(&given)
        ));
    }
    notes
}

/// Fills the time settings not `named` from `recorded` when the named ones still read a time
/// column (not a named sample rate, and not a recorded sample rate, which has no column to
/// inherit a unit for); returns what was taken, in words, or `None`.
fn inherit_time(recorded: &LogTimeRecord, format: &mut LogFormat, named: TimeNamed) -> Option<String> {
    if named.sample_rate || recorded.sample_rate_hz > 0.0 {
        return None;
    }
    // Only what differs from the defaults is worth a note.
    let defaults = LogFormat::default();
    let mut taken = Vec::new();
    if !named.column {
        format.time_column.clone_from(&recorded.column);
        if recorded.column != defaults.time_column {
            taken.push(format!("the time column '{}'", recorded.column));
        }
    }
    if !named.unit {
        let unit = crate::ingest::TimeUnit::from_log_unit(recorded.unit);
        format.time_unit = unit;
        if unit != defaults.time_unit {
            taken.push(format!("the time unit {}", unit.option_name()));
        }
    }
    if !named.date && !recorded.date_column.is_empty() {
        format.date_column = Some(recorded.date_column.clone());
        taken.push(format!("the date column '{}'", recorded.date_column));
    }
    (!taken.is_empty()).then(|| format!("the logs' time is read with {}", taken.join(" and ")))
}

/// A log-time record in words: `column 'time (ms)' in ms`, `the row index at 50 Hz`.
pub fn describe_time(record: &LogTimeRecord) -> String {
    if record.sample_rate_hz > 0.0 {
        return format!("the row index at {} Hz (no time column)", record.sample_rate_hz);
    }
    let unit = crate::ingest::TimeUnit::from_log_unit(record.unit).option_name();
    if record.date_column.is_empty() {
        format!("column '{}' in {unit}", record.column)
    } else {
        format!("column '{}' with the date column '{}', in {unit}", record.column, record.date_column)
    }
}

/// The columns to read `model` with: `gyro` and `temp` as named (empty: not named) checked
/// against the ones the model records, or the recorded ones where none are named, or the
/// defaults of [`LogFormat`] for a model that records none. `model_name` and the option
/// names (`gyro_setting`, `temp_setting`) are for the messages.
///
/// # Errors
/// [`SwappedColumn`] when a named column is one the model fitted another axis on.
pub fn choose(
    model: &Model<'_>,
    model_name: &str,
    (gyro, temp): (&[String], &[String]),
    (gyro_setting, temp_setting): (&str, &str),
) -> Result<ChosenColumns, Box<SwappedColumn>> {
    let recorded: Option<Vec<ColumnNames>> =
        (0..model.axis_count()).map(|a| ColumnNames::of(model, a)).collect();
    let defaults = LogFormat::default();
    let Some(recorded) = recorded else {
        return Ok(ChosenColumns {
            gyro: if gyro.is_empty() { defaults.gyro_columns } else { gyro.to_vec() },
            temp: if temp.is_empty() { defaults.temp_columns } else { temp.to_vec() },
            ..ChosenColumns::default()
        });
    };
    let recorded_gyro: Vec<&str> = recorded.iter().map(|c| c.gyro.as_str()).collect();
    let recorded_temp: Vec<&str> = recorded.iter().map(|c| c.temp.as_str()).collect();
    let gyro_from_model = gyro.is_empty() && recorded_gyro.iter().all(|n| !n.is_empty());
    let chosen_gyro = if gyro_from_model {
        recorded_gyro.iter().map(|n| (*n).to_string()).collect()
    } else if gyro.is_empty() {
        defaults.gyro_columns
    } else {
        gyro.to_vec()
    };
    let axes = chosen_gyro.len().min(recorded.len());
    let chosen_temp = if !temp.is_empty() {
        temp.to_vec()
    } else if recorded_temp[..axes].iter().any(|n| n.is_empty()) {
        defaults.temp_columns
    } else if recorded_temp[..axes].iter().all(|n| *n == recorded_temp[0]) {
        vec![recorded_temp[0].to_string()]
    } else {
        recorded_temp[..axes].iter().map(|n| (*n).to_string()).collect()
    };
    let mut notes = Vec::new();
    let per_axis_gyro: Vec<&str> = chosen_gyro.iter().map(String::as_str).collect();
    check(model_name, gyro_setting, &per_axis_gyro, &recorded_gyro, Kind::Gyro, &mut notes)?;
    let per_axis_temp: Vec<&str> = (0..axes)
        .map(|a| chosen_temp.get(a.min(chosen_temp.len().saturating_sub(1))).map_or("", String::as_str))
        .collect();
    check(model_name, temp_setting, &per_axis_temp, &recorded_temp, Kind::Temperature, &mut notes)?;
    Ok(ChosenColumns { gyro: chosen_gyro, temp: chosen_temp, notes, gyro_from_model })
}

/// The units to read the logs of `model` in: where no unit option was named (`named`: the
/// gyro's, the temperature's), the ones the model records, which its fit read the logs in;
/// `format`'s where they were named. Returns the notes: the units taken from the model when
/// they are not the defaults (deg/h, deg C), and named units that differ from the model's.
/// A model that records none (before format 4) leaves `format` as it is. `settings` names the
/// options for the messages (`--gyro-unit/--gyro-scale`, `--temp-scale/--temp-offset`).
pub fn choose_units(
    model: &Model<'_>,
    model_name: &str,
    format: &mut LogFormat,
    (gyro_named, temp_named): (bool, bool),
    (gyro_setting, temp_setting): (&str, &str),
) -> Vec<String> {
    let Some(fitted) = ColumnNames::of(model, 0) else { return Vec::new() };
    let mut notes = Vec::new();
    let same = |a: f64, b: f64| (a - b).abs() <= 1e-6 * (a.abs() + b.abs() + 1e-30);
    let gyro_given = format.gyro_unit.dph() * format.gyro_scale;
    // Printed to 7 significant digits (f32's shortest text).
    let fitted_gyro = format!("{} deg/h per unit", fitted.gyro_dph_per_unit as f32);
    if !gyro_named {
        format.gyro_unit = RateUnit::DegPerHour;
        format.gyro_scale = fitted.gyro_dph_per_unit;
        if fitted.gyro_dph_per_unit != 1.0 {
            notes.push(format!("{model_name}: the gyro is read as the model was fitted: {fitted_gyro} ({gyro_setting} to read it otherwise)"));
        }
    } else if !same(gyro_given, fitted.gyro_dph_per_unit) {
        notes.push(format!(
            "{model_name} was fitted on the gyro read as {fitted_gyro}; this log is read as {} deg/h per unit ({gyro_setting})",
            gyro_given as f32
        ));
    }
    let temp = |scale: f64, offset: f64| {
        let sign = if offset < 0.0 { "-" } else { "+" };
        format!("{} C per unit {sign} {} C", scale as f32, offset.abs() as f32)
    };
    let fitted_temp = temp(fitted.temp_c_per_unit, fitted.temp_offset_c);
    if !temp_named {
        format.temp_scale = fitted.temp_c_per_unit;
        format.temp_offset_c = fitted.temp_offset_c;
        if fitted.temp_c_per_unit != 1.0 || fitted.temp_offset_c != 0.0 {
            notes.push(format!("{model_name}: the temperature is read as the model was fitted: {fitted_temp} ({temp_setting} to read it otherwise)"));
        }
    } else if !(same(format.temp_scale, fitted.temp_c_per_unit)
        && (format.temp_offset_c - fitted.temp_offset_c).abs() <= 1e-4)
    {
        notes.push(format!(
            "{model_name} was fitted on the temperature read as {fitted_temp}; this log is read as {} ({temp_setting})",
            temp(format.temp_scale, format.temp_offset_c)
        ));
    }
    notes
}

/// The two kinds of column an axis reads.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Gyro,
    Temperature,
}

/// Compares the column each axis is read with (`used`) against the one it was fitted on
/// (`recorded`). Another axis's gyro column is [`SwappedColumn`]; another axis's temperature
/// column (one sensor for all axes, say) and a name the model does not know (a log from
/// another logger may name the same sensor differently) are notes.
fn check(
    model_name: &str,
    setting: &str,
    used: &[&str],
    recorded: &[&str],
    kind: Kind,
    notes: &mut Vec<String>,
) -> Result<(), Box<SwappedColumn>> {
    for (axis, (&given, &fitted)) in used.iter().zip(recorded).enumerate() {
        if given == fitted || fitted.is_empty() {
            continue;
        }
        let other_axis = recorded.iter().position(|n| *n == given);
        let note = match (kind, other_axis) {
            (Kind::Gyro, Some(other_axis)) => {
                return Err(Box::new(SwappedColumn {
                    model: model_name.to_string(),
                    setting: setting.to_string(),
                    axis,
                    given: given.to_string(),
                    fitted: fitted.to_string(),
                    other_axis,
                    order: recorded.iter().map(|n| format!("{setting} {n}")).collect::<Vec<_>>().join(" "),
                }))
            }
            (Kind::Gyro, None) => format!(
                "{model_name}: axis {axis} was fitted on the gyro column '{fitted}'; the log's column '{given}' \
                 ({setting}) is compensated with it"
            ),
            (Kind::Temperature, Some(other_axis)) => format!(
                "{model_name}: axis {axis} was fitted with the temperature column '{fitted}'; it is read with \
                 '{given}' ({setting}), the column axis {other_axis} was fitted with"
            ),
            (Kind::Temperature, None) => format!(
                "{model_name}: axis {axis} was fitted with the temperature column '{fitted}'; the log's column \
                 '{given}' ({setting}) is used in its place"
            ),
        };
        notes.push(note);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blob::{encode, ModelFile};
    use fogtemp_core::PolyTerm;

    /// A blob of constant-bias axes recording `names` (gyro, temperature) per axis, or none.
    fn model_with(axes: usize, names: &[(&str, &str)]) -> Vec<u8> {
        let axis = crate::blob::test_poly_axis(vec![PolyTerm {
            temp_power: 0,
            rate_power: 0,
            coefficient_dph: 1.0,
        }]);
        let columns = names
            .iter()
            .map(|(g, t)| ColumnNames { gyro: (*g).into(), temp: (*t).into(), ..ColumnNames::default() })
            .collect();
        let file = ModelFile {
            tool_version: String::new(),
            input_digest: [0; 32],
            axes: vec![axis; axes],
            columns,
            log_time: Default::default(),
            log_reading: Default::default(),
            input_rates: None,
        };
        encode(&file).expect("encodes")
    }

    /// A one-axis model fitted on `gyrox` in rad/s at half scale and `temp` in 1/256 C counts
    /// from -231 C (the README's psim-tvc command).
    fn psim_like() -> Vec<u8> {
        let axis = crate::blob::test_poly_axis(vec![PolyTerm {
            temp_power: 0,
            rate_power: 0,
            coefficient_dph: 1.0,
        }]);
        let columns = vec![ColumnNames {
            gyro: "gyrox".into(),
            temp: "temp".into(),
            gyro_dph_per_unit: RateUnit::RadPerSecond.dph() * 0.5,
            temp_c_per_unit: 0.00390625,
            temp_offset_c: -231.0,
        }];
        encode(&ModelFile {
            tool_version: String::new(),
            input_digest: [0; 32],
            axes: vec![axis],
            columns,
            log_time: Default::default(),
            log_reading: Default::default(),
            input_rates: None,
        })
        .expect("encodes")
    }

    fn units(blob: &[u8], format: &mut LogFormat, named: (bool, bool)) -> Vec<String> {
        let model = Model::from_bytes(blob).expect("valid");
        choose_units(
            &model,
            "m.fogm",
            format,
            named,
            ("--gyro-unit/--gyro-scale", "--temp-scale/--temp-offset"),
        )
    }

    #[test]
    fn units_not_named_are_the_models_and_named_ones_that_differ_are_noted() {
        let blob = psim_like();
        // Not named: the model's, said once each (they are not deg/h and deg C).
        let mut format = LogFormat::default();
        let notes = units(&blob, &mut format, (false, false));
        // 0.5 rad/s in deg/h: 0.5 * 3600 * 180 / pi.
        let dph = 0.5 * 3600.0 * 180.0 / std::f64::consts::PI;
        assert_eq!(format.gyro_unit, RateUnit::DegPerHour);
        assert!((format.gyro_scale - dph).abs() <= 1e-7 * dph, "{}", format.gyro_scale);
        assert_eq!((format.temp_scale, format.temp_offset_c), (0.00390625, -231.0));
        assert_eq!(notes.len(), 2, "{notes:?}");
        assert!(
            notes[0].starts_with("m.fogm: the gyro is read as the model was fitted: 103132.4"),
            "{notes:?}"
        );
        assert!(notes[1].contains("0.00390625 C per unit - 231 C (--temp-scale/--temp-offset"), "{notes:?}");
        // Named as fitted: nothing to say; named otherwise: used, with a note.
        let mut format = LogFormat {
            gyro_unit: RateUnit::RadPerSecond,
            gyro_scale: 0.5,
            temp_scale: 0.00390625,
            temp_offset_c: -231.0,
            ..LogFormat::default()
        };
        assert!(units(&blob, &mut format, (true, true)).is_empty());
        let mut format = LogFormat::default();
        let notes = units(&blob, &mut format, (true, true));
        assert_eq!((format.gyro_scale, format.temp_scale), (1.0, 1.0));
        assert_eq!(notes.len(), 2, "{notes:?}");
        assert!(
            notes[0].contains("this log is read as 1 deg/h per unit (--gyro-unit/--gyro-scale)"),
            "{notes:?}"
        );
        // A model with default units, or one that records none, leaves the format alone.
        for blob in [model_with(1, &[("g", "t")]), model_with(1, &[])] {
            let mut format = LogFormat { gyro_scale: 2.0, ..LogFormat::default() };
            assert!(units(&blob, &mut format, (false, false)).is_empty());
        }
    }

    fn strings(names: &[&str]) -> Vec<String> {
        names.iter().map(|n| (*n).to_string()).collect()
    }

    fn chosen(blob: &[u8], gyro: &[&str], temp: &[&str]) -> Result<ChosenColumns, Box<SwappedColumn>> {
        let model = Model::from_bytes(blob).expect("valid");
        choose(&model, "m.fogm", (&strings(gyro), &strings(temp)), ("--gyro-column", "--temp-column"))
    }

    #[test]
    fn nothing_named_reads_the_recorded_columns_and_a_shared_temperature_once() {
        let blob = model_with(2, &[("gyro_x", "temp_c"), ("gyro_y", "temp_c")]);
        let c = chosen(&blob, &[], &[]).expect("chosen");
        assert_eq!(
            (c.gyro, c.temp, c.gyro_from_model),
            (strings(&["gyro_x", "gyro_y"]), strings(&["temp_c"]), true)
        );
        assert!(c.notes.is_empty());
        let blob = model_with(2, &[("gx", "tx"), ("gy", "ty")]);
        assert_eq!(chosen(&blob, &[], &[]).expect("chosen").temp, strings(&["tx", "ty"]));
    }

    #[test]
    fn a_model_without_names_reads_what_is_named_or_the_defaults_by_position() {
        let blob = model_with(2, &[]);
        let c = chosen(&blob, &[], &[]).expect("chosen");
        assert_eq!(
            (c.gyro, c.temp, c.gyro_from_model),
            (strings(&["gyro_dph"]), strings(&["temp_c"]), false)
        );
        let c = chosen(&blob, &["b", "a"], &[]).expect("chosen");
        assert_eq!(c.gyro, strings(&["b", "a"]));
        assert!(c.notes.is_empty());
    }

    #[test]
    fn swapped_gyro_columns_are_refused_naming_both_axes_and_the_order() {
        let blob = model_with(2, &[("gyro_x", "temp_c"), ("gyro_y", "temp_c")]);
        let e = chosen(&blob, &["gyro_y", "gyro_x"], &[]).expect_err("swapped");
        assert_eq!((e.axis, e.given.as_str(), e.fitted.as_str(), e.other_axis), (0, "gyro_y", "gyro_x", 1));
        assert_eq!(e.order, "--gyro-column gyro_x --gyro-column gyro_y");
        // One column that the model fitted axis 1 on, read as axis 0: the review's case.
        let e = chosen(&blob, &["gyro_y"], &[]).expect_err("axis 1's column as axis 0");
        assert_eq!((e.axis, e.other_axis), (0, 1));
        // The model's order, or a prefix of it, is what was fitted: no note.
        for named in [&["gyro_x", "gyro_y"][..], &["gyro_x"]] {
            let c = chosen(&blob, named, &[]).expect("in order");
            assert!(c.notes.is_empty() && !c.gyro_from_model);
        }
    }

    #[test]
    fn unknown_names_and_borrowed_temperatures_are_used_with_a_note() {
        let blob = model_with(2, &[("gyro_x", "tx"), ("gyro_y", "ty")]);
        let c = chosen(&blob, &["gx", "gyro_y"], &["tx"]).expect("renamed");
        assert_eq!(c.gyro, strings(&["gx", "gyro_y"]));
        assert_eq!(c.notes.len(), 2, "{:?}", c.notes);
        assert!(c.notes[0].contains("axis 0 was fitted on the gyro column 'gyro_x'; the log's column 'gx'"));
        assert!(
            c.notes[1].contains("axis 1 was fitted with the temperature column 'ty'; it is read with 'tx'")
        );
        assert!(c.notes[1].contains("the column axis 0 was fitted with"));
    }

    /// A model recording `record` as its logs' time.
    fn model_timed(record: LogTimeRecord) -> Vec<u8> {
        let axis = crate::blob::test_poly_axis(vec![PolyTerm {
            temp_power: 0,
            rate_power: 0,
            coefficient_dph: 1.0,
        }]);
        let file = ModelFile {
            tool_version: String::new(),
            input_digest: [0; 32],
            axes: vec![axis],
            columns: vec![ColumnNames {
                gyro: "gyro_dph".into(),
                temp: "temp_c".into(),
                ..ColumnNames::default()
            }],
            log_time: record,
            log_reading: Default::default(),
            input_rates: None,
        };
        encode(&file).expect("encodes")
    }

    fn time(blob: &[u8], format: &mut LogFormat, named: TimeNamed) -> Vec<String> {
        let model = Model::from_bytes(blob).expect("valid");
        choose_time(&model, "m.fogm", format, named, "--time-*")
    }

    #[test]
    fn a_named_time_column_is_read_in_the_recorded_unit_and_date_column() {
        use crate::ingest::TimeUnit;
        let blob = model_timed(LogTimeRecord {
            column: "time (ms)".into(),
            date_column: String::new(),
            unit: fogtemp_core::LogTimeUnit::Milliseconds,
            sample_rate_hz: 0.0,
        });
        // Nothing named: the record, said once.
        let mut format = LogFormat::default();
        let notes = time(&blob, &mut format, TimeNamed::default());
        assert_eq!((format.time_column.as_str(), format.time_unit), ("time (ms)", TimeUnit::Milliseconds));
        assert_eq!(notes.len(), 1, "{notes:?}");
        // Only the column named (another logger's name): still milliseconds, with both notes.
        let mut format = LogFormat { time_column: "t".into(), ..LogFormat::default() };
        let notes = time(&blob, &mut format, TimeNamed { column: true, ..TimeNamed::default() });
        assert_eq!((format.time_column.as_str(), format.time_unit), ("t", TimeUnit::Milliseconds));
        assert_eq!(notes.len(), 2, "{notes:?}");
        assert!(notes[0].contains("read with the time unit ms, as m.fogm records"), "{}", notes[0]);
        assert!(notes[1].contains("column 't' in ms: used as given"), "{}", notes[1]);
        // Only the unit named: the recorded column in that unit.
        let mut format = LogFormat { time_unit: TimeUnit::Microseconds, ..LogFormat::default() };
        let notes = time(&blob, &mut format, TimeNamed { unit: true, ..TimeNamed::default() });
        assert_eq!((format.time_column.as_str(), format.time_unit), ("time (ms)", TimeUnit::Microseconds));
        assert!(notes[0].contains("the time column 'time (ms)'"), "{notes:?}");
        // A named sample rate replaces the time column and inherits nothing.
        let mut format = LogFormat { sample_rate_hz: Some(50.0), ..LogFormat::default() };
        let notes = time(&blob, &mut format, TimeNamed { sample_rate: true, ..TimeNamed::default() });
        assert_eq!(format.sample_rate_hz, Some(50.0));
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(notes[0].contains("the row index at 50 Hz"), "{}", notes[0]);
        // Everything named as recorded: no note.
        let mut format = LogFormat {
            time_column: "time (ms)".into(),
            time_unit: TimeUnit::Milliseconds,
            ..LogFormat::default()
        };
        let both = TimeNamed { column: true, unit: true, ..TimeNamed::default() };
        assert!(time(&blob, &mut format, both).is_empty());
    }

    #[test]
    fn a_recorded_date_column_is_kept_when_only_the_time_column_is_renamed() {
        use crate::ingest::TimeUnit;
        let blob = model_timed(LogTimeRecord {
            column: "clock".into(),
            date_column: "day".into(),
            unit: fogtemp_core::LogTimeUnit::DateTime,
            sample_rate_hz: 0.0,
        });
        let mut format = LogFormat { time_column: "hhmmss".into(), ..LogFormat::default() };
        let notes = time(&blob, &mut format, TimeNamed { column: true, ..TimeNamed::default() });
        assert_eq!(format.date_column.as_deref(), Some("day"));
        assert_eq!(format.time_unit, TimeUnit::DateTime);
        assert!(notes[0].contains("the time unit datetime and the date column 'day'"), "{notes:?}");
    }
}
