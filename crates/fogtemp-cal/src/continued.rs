//! Logs that continue one another: one run split over several files (a logger that starts a
//! new file every hour or every N MB).
//!
//! Every log is read as a power-on run of its own: the feature tracker and the compensator
//! start again in each, and the bias stability is computed per file. For the parts of one
//! run that is silently optimistic (review12 finding 2: a 2 h run split in three read 0.01027,
//! 0.00337 and 0.00505 deg/h against 0.01159 whole). A log whose first time stamp follows
//! another's last by more than 0 and at most the tracker's `max_gap_s` (a gap the tracker
//! would have bridged had the two been one file), and whose first temperature reading the
//! other's last can reach in that time, is named with the one it continues, so the reader can
//! join them. So is a log that starts with the other's last row again, at the same time stamp
//! and temperature reading (some loggers repeat it at the top of a new file; review13 F10).
//! Logs whose time restarts at 0 in every file never match.

use std::path::{Path, PathBuf};

use crate::ingest::IngestReport;

/// Logs that continue one another in time.
#[derive(Clone, Debug, PartialEq)]
pub enum Continued {
    /// Logs read one after another: each starts at most `max_gap_s` after the one before it
    /// ends, and no other log ends or starts so.
    Chain {
        /// The logs, earliest first.
        parts: Vec<PathBuf>,
        /// The longest step from one part's last time stamp to the next's first, s.
        largest_step_s: f64,
        /// Per part after the first: whether it starts with the previous part's last row
        /// again (a step of 0 s), which a join must drop.
        repeats_last_row: Vec<bool>,
    },
    /// Logs that each start at most `max_gap_s` after one of several others ends (runs in
    /// relative time of the same length, each split alike): which part continues which
    /// cannot be told from the time stamps.
    Unpaired {
        /// The logs that start after another ends.
        later: Vec<PathBuf>,
        /// The logs they may continue.
        earlier: Vec<PathBuf>,
        /// The longest such step, s.
        largest_step_s: f64,
    },
}

/// A log's path, its first and last time stamps (s, in the log's clock) and its first and
/// last temperature readings (deg C).
struct Span<'a> {
    path: &'a Path,
    first_s: f64,
    last_s: f64,
    temp_ends_c: Option<(f64, f64)>,
}

/// The logs among `reports` that continue one another: the chains (earliest first, each at
/// least two logs, in the order of their first log's time), then, when some log could
/// continue more than one or be continued by more than one, those logs together. A log read
/// twice (the same path) counts once; logs without rows never match.
pub fn continued_logs<'a>(
    reports: impl IntoIterator<Item = &'a IngestReport>,
    max_gap_s: f64,
) -> Vec<Continued> {
    let mut spans: Vec<Span<'_>> = Vec::new();
    for r in reports {
        let (first_s, last_s) = (r.time_origin_s, r.time_origin_s + r.last_time_s);
        if r.rows > 0 && first_s.is_finite() && last_s.is_finite() && !spans.iter().any(|s| s.path == r.path)
        {
            spans.push(Span { path: r.path.as_path(), first_s, last_s, temp_ends_c: r.temp_ends_c });
        }
    }
    spans.sort_by(|a, b| a.first_s.total_cmp(&b.first_s));
    let step = |earlier: &Span<'_>, later: &Span<'_>| later.first_s - earlier.last_s;
    let repeats_last_row = |earlier: &Span<'_>, later: &Span<'_>| {
        let same_reading = matches!((earlier.temp_ends_c, later.temp_ends_c), (Some((_, last)), Some((first, _))) if first == last);
        later.first_s == earlier.last_s && earlier.last_s > earlier.first_s && same_reading
    };
    // The later log starts within the gap, at a temperature the earlier one's last reading
    // can reach in that time (the glitch limit of `crate::spikes`: a -35 C run logged one
    // second after a +10 C run ended does not continue it, review13 F4).
    let follows = |j: usize, i: usize| {
        let s = step(&spans[j], &spans[i]);
        let temperature_carries_on = match (spans[j].temp_ends_c, spans[i].temp_ends_c) {
            (Some((_, last)), Some((first, _))) => (first - last).abs() <= crate::spikes::jump_limit_c(s),
            _ => true,
        };
        s > 0.0 && s <= max_gap_s && temperature_carries_on || repeats_last_row(&spans[j], &spans[i])
    };
    let n = spans.len();
    let before: Vec<Vec<usize>> = (0..n).map(|i| (0..n).filter(|&j| follows(j, i)).collect()).collect();
    let mut after: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, earlier) in before.iter().enumerate() {
        earlier.iter().for_each(|&j| after[j].push(i));
    }
    // A link where each is the other's only candidate.
    let next: Vec<Option<usize>> = (0..n)
        .map(|j| after[j].first().copied().filter(|&i| after[j].len() == 1 && before[i] == [j]))
        .collect();
    let linked_to: Vec<bool> = (0..n).map(|i| next.contains(&Some(i))).collect();
    let mut found = Vec::new();
    for start in (0..n).filter(|&i| !linked_to[i] && next[i].is_some()) {
        let (mut parts, mut largest_step_s, mut at) = (vec![spans[start].path.to_path_buf()], 0.0_f64, start);
        let mut repeats = Vec::new();
        while let Some(i) = next[at] {
            largest_step_s = largest_step_s.max(step(&spans[at], &spans[i]));
            repeats.push(repeats_last_row(&spans[at], &spans[i]));
            parts.push(spans[i].path.to_path_buf());
            at = i;
        }
        found.push(Continued::Chain { parts, largest_step_s, repeats_last_row: repeats });
    }
    let later: Vec<usize> = (0..n).filter(|&i| !before[i].is_empty() && !linked_to[i]).collect();
    if !later.is_empty() {
        let mut earlier: Vec<usize> = later.iter().flat_map(|&i| before[i].iter().copied()).collect();
        earlier.sort_unstable();
        earlier.dedup();
        let largest_step_s = later
            .iter()
            .flat_map(|&i| before[i].iter().map(move |&j| (j, i)))
            .map(|(j, i)| step(&spans[j], &spans[i]));
        found.push(Continued::Unpaired {
            later: later.iter().map(|&i| spans[i].path.to_path_buf()).collect(),
            earlier: earlier.iter().map(|&j| spans[j].path.to_path_buf()).collect(),
            largest_step_s: largest_step_s.fold(0.0, f64::max),
        });
    }
    found
}

/// What reading split parts as runs of their own does.
const READ_APART: &str =
    "Each log is read as a run of its own (the features and the compensator start again \
                          in each, and each part gets a bias stability of its own, not the whole run's)";

/// How the join command must change for other log shapes.
const OTHER_SHAPES: &str =
    "for logs whose data start on line 2; with banner lines or without a header, start \
                            each later part at its first data line instead (tail -n +K)";

impl Continued {
    /// What the reader is told: which logs, why they look like one run, what reading them
    /// apart does, and how to join them.
    pub fn message(&self) -> String {
        match self {
            Continued::Chain { parts, largest_step_s, repeats_last_row } => {
                let names: Vec<String> = parts.iter().map(|p| p.display().to_string()).collect();
                let (first, rest) = names.split_first().map_or(("", &[][..]), |(f, r)| (f.as_str(), r));
                let first_kept_line = |k: usize| if repeats_last_row.get(k) == Some(&true) { 3 } else { 2 };
                let join: Vec<String> = std::iter::once(format!("cat {first}"))
                    .chain(rest.iter().enumerate().map(|(k, r)| format!("tail -n +{} {r}", first_kept_line(k))))
                    .collect();
                let repeated: Vec<&str> = rest
                    .iter()
                    .zip(repeats_last_row)
                    .filter(|(_, repeats)| **repeats)
                    .map(|(r, _)| r.as_str())
                    .collect();
                let repeated = match repeated.len() {
                    0 => String::new(),
                    // Only the time stamp and temperature are compared (review15 F8).
                    1 => format!(
                        "; {} starts at the time stamp and temperature reading of the last row before it (that row \
                         logged again?), which the join drops",
                        repeated.join("")
                    ),
                    _ => format!(
                        "; {} start at the time stamp and temperature reading of the last row before them (that row \
                         logged again?), which the join drops",
                        repeated.join(", ")
                    ),
                };
                let listed = match names.split_last() {
                    Some((last, before)) if !before.is_empty() => format!("{} and {last}", before.join(", ")),
                    _ => names.join(""),
                };
                format!(
                    "{listed} follow one another in time (each starts at most {} s after the one before it ends{repeated}): \
                     one run split over files? {READ_APART}; to read them as one run, join them first, e.g. {{ {}; }} > \
                     joined.csv ({OTHER_SHAPES})",
                    seconds(*largest_step_s),
                    join.join("; "),
                )
            }
            Continued::Unpaired { later, earlier, largest_step_s } => format!(
                "{} each start at most {} s after one of {} ends, and the time stamps cannot tell which: runs split \
                 over files, with a clock that counts on from the previous part? {READ_APART}; to read a run as one, \
                 join its parts in order first (cat the first, then tail -n +2 each later part, {OTHER_SHAPES})",
                names(later),
                seconds(*largest_step_s),
                names(earlier),
            ),
        }
    }
}

/// Up to four names, then how many more.
fn names(paths: &[PathBuf]) -> String {
    let shown: Vec<String> = paths.iter().take(4).map(|p| p.display().to_string()).collect();
    match paths.len() {
        n if n > 4 => format!("{} and {} more", shown.join(", "), n - 4),
        _ => shown.join(", "),
    }
}

/// A step in seconds, without trailing zeros (`1`, `0.02`).
fn seconds(step_s: f64) -> String {
    let text = format!("{step_s:.3}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(name: &str, first_s: f64, last_s: f64) -> IngestReport {
        IngestReport {
            path: PathBuf::from(name),
            rows: 10,
            time_origin_s: first_s,
            last_time_s: last_s - first_s,
            ..IngestReport::default()
        }
    }

    #[test]
    fn parts_that_follow_within_the_gap_form_one_chain_in_time_order() {
        // A 2 h run in three files, given out of order, beside a run of its own.
        let reports = [
            report("b2.csv", 2400.0, 4799.0),
            report("b1.csv", 0.0, 2399.0),
            report("other.csv", 0.0, 7199.0),
            report("b3.csv", 4800.0, 7199.0),
        ];
        let chains = continued_logs(&reports, 5.0);
        assert_eq!(chains.len(), 1, "{chains:?}");
        let Continued::Chain { parts, largest_step_s, .. } = &chains[0] else { panic!("{chains:?}") };
        let names: Vec<_> = parts.iter().map(|p| p.display().to_string()).collect();
        assert_eq!(names, ["b1.csv", "b2.csv", "b3.csv"]);
        assert_eq!(*largest_step_s, 1.0);
        let text = chains[0].message();
        assert!(
            text.starts_with(
                "b1.csv, b2.csv and b3.csv follow one another in time (each starts at most 1 s after"
            ),
            "{text}"
        );
        assert!(
            text.contains("{ cat b1.csv; tail -n +2 b2.csv; tail -n +2 b3.csv; } > joined.csv"),
            "{text}"
        );
    }

    #[test]
    fn logs_that_restart_their_clock_overlap_or_leave_a_long_gap_are_apart() {
        // Every log from 0 (the usual relative time), an overlap, and a step beyond the gap.
        let restart = [report("a.csv", 0.0, 3600.0), report("b.csv", 0.0, 3600.0)];
        assert!(continued_logs(&restart, 5.0).is_empty());
        let overlap = [report("a.csv", 0.0, 3600.0), report("b.csv", 3599.0, 7200.0)];
        assert!(continued_logs(&overlap, 5.0).is_empty());
        let apart = [report("a.csv", 0.0, 3600.0), report("b.csv", 3605.5, 7200.0)];
        assert!(continued_logs(&apart, 5.0).is_empty());
        assert_eq!(continued_logs(&apart, 6.0).len(), 1);
        // The same log twice (validate with two models) counts once.
        let twice = [report("a.csv", 0.0, 3600.0), report("a.csv", 0.0, 3600.0)];
        assert!(continued_logs(&twice, 5.0).is_empty());
        // A log without rows never matches.
        let empty =
            [report("a.csv", 0.0, 3600.0), IngestReport { rows: 0, ..report("b.csv", 3601.0, 3601.0) }];
        assert!(continued_logs(&empty, 5.0).is_empty());
    }

    #[test]
    fn a_log_that_starts_at_another_temperature_does_not_continue() {
        // Back to back in one clock: a +10 C run ends at 20 C, a -35 C run starts 1 s later.
        let warm = IngestReport { temp_ends_c: Some((10.0, 20.0)), ..report("warm.csv", 0.0, 7199.0) };
        let cold = IngestReport { temp_ends_c: Some((-35.0, -20.0)), ..report("cold.csv", 7200.0, 14399.0) };
        assert!(continued_logs(&[warm.clone(), cold], 5.0).is_empty());
        // The same run's next part starts where the last reading left it (within 1 C).
        let next = IngestReport { temp_ends_c: Some((20.4, 25.0)), ..report("next.csv", 7200.0, 14399.0) };
        assert_eq!(continued_logs(&[warm, next], 5.0).len(), 1);
    }

    #[test]
    fn parts_of_runs_that_share_one_relative_clock_are_named_together_unpaired() {
        // Two 2 h runs, each split at 2400 s, both clocks from 0: which second part goes
        // with which first cannot be told. A third run, in absolute time, pairs on its own.
        let reports = [
            report("a1.csv", 0.0, 2399.0),
            report("a2.csv", 2400.0, 4799.0),
            report("b1.csv", 0.0, 2399.0),
            report("b2.csv", 2400.0, 4799.0),
            report("c1.csv", 1e6, 1e6 + 2399.0),
            report("c2.csv", 1e6 + 2400.0, 1e6 + 4799.0),
        ];
        let found = continued_logs(&reports, 5.0);
        assert_eq!(found.len(), 2, "{found:?}");
        assert!(
            matches!(&found[0], Continued::Chain { parts, .. } if parts.len() == 2 && parts[0].ends_with("c1.csv"))
        );
        let Continued::Unpaired { later, earlier, largest_step_s } = &found[1] else { panic!("{found:?}") };
        let text = |p: &[PathBuf]| p.iter().map(|p| p.display().to_string()).collect::<Vec<_>>();
        assert_eq!(
            (text(later), text(earlier), *largest_step_s),
            (vec!["a2.csv".to_string(), "b2.csv".into()], vec!["a1.csv".to_string(), "b1.csv".into()], 1.0)
        );
        assert!(
            found[1]
                .message()
                .starts_with("a2.csv, b2.csv each start at most 1 s after one of a1.csv, b1.csv ends"),
            "{}",
            found[1].message()
        );
    }

    #[test]
    fn a_part_that_repeats_the_last_row_continues_and_the_join_drops_the_repeat() {
        let at = |name: &str, first_s: f64, last_s: f64, temps: (f64, f64)| IngestReport {
            temp_ends_c: Some(temps),
            ..report(name, first_s, last_s)
        };
        // The second part starts at the first part's last time stamp with its last reading.
        let parts = [
            at("p1.csv", 0.0, 2399.0, (10.0, 14.5)),
            at("p2.csv", 2399.0, 4799.0, (14.5, 18.0)),
            at("p3.csv", 4800.0, 7199.0, (18.0625, 20.0)),
        ];
        let found = continued_logs(&parts, 5.0);
        let [Continued::Chain { parts: names, repeats_last_row, .. }] = &found[..] else {
            panic!("{found:?}")
        };
        assert_eq!(names.len(), 3);
        assert_eq!(repeats_last_row, &[true, false]);
        let text = found[0].message();
        assert!(
            text.contains("{ cat p1.csv; tail -n +3 p2.csv; tail -n +2 p3.csv; } > joined.csv"),
            "{text}"
        );
        assert!(
            text.contains(
                "p2.csv starts at the time stamp and temperature reading of the last row before it"
            ),
            "{text}"
        );
        // The same time stamp with another reading, or a log of one time stamp, is no repeat.
        let other = [at("p1.csv", 0.0, 2399.0, (10.0, 14.5)), at("p2.csv", 2399.0, 4799.0, (14.4375, 18.0))];
        assert!(continued_logs(&other, 5.0).is_empty());
        let single = [at("s.csv", 0.0, 0.0, (14.5, 14.5)), at("r.csv", 0.0, 3600.0, (14.5, 20.0))];
        assert!(continued_logs(&single, 5.0).is_empty());
    }
}
