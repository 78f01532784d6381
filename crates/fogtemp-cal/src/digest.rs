//! The model's input digest (`docs/model-format.md`: SHA-256 over the calibration logs'
//! bytes, one after another, in the order they were read), and what `validate` says when the
//! logs it is given are the ones a model was fitted on.

use std::io::Read;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use fogtemp_core::Model;

use crate::blob::{short_digest, LogReadingRecord};
use crate::error::CalError;

/// The digest of the logs together (the model's input digest) and of each alone, in order.
pub type Digests = ([u8; 32], Vec<[u8; 32]>);

/// The input digest built one file at a time (a caller can stop between two files), with
/// each file's own digest beside it.
#[derive(Clone, Debug, Default)]
pub struct InputDigest {
    all: Sha256,
    each: Vec<[u8; 32]>,
}

impl InputDigest {
    /// An empty digest.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds the bytes of the file at `path`.
    ///
    /// # Errors
    /// [`CalError::Io`] naming the file that cannot be opened or read.
    pub fn add_file(&mut self, path: &Path) -> Result<(), CalError> {
        let io = |source| CalError::Io { path: path.to_path_buf(), source };
        let mut file = std::fs::File::open(path).map_err(io)?;
        let mut one = Sha256::new();
        let mut buf = vec![0u8; 1 << 20];
        loop {
            let n = file.read(&mut buf).map_err(io)?;
            if n == 0 {
                break;
            }
            self.all.update(&buf[..n]);
            one.update(&buf[..n]);
        }
        self.each.push(one.finalize().into());
        Ok(())
    }

    /// A reader over `inner` that adds the bytes it yields to this digest as they are read,
    /// so that a log's digest comes with its one read (`ingest::read_log_digested`). The
    /// digest takes them only at [`DigestingReader::finish`]: a read that fails leaves it as
    /// it was.
    pub fn reading<R: Read>(&mut self, inner: R) -> DigestingReader<'_, R> {
        DigestingReader { all: self.all.clone(), one: Sha256::new(), inner, digest: self }
    }

    /// The digest of the files together and of each alone, in the order they were added.
    pub fn finish(self) -> Digests {
        (self.all.finalize().into(), self.each)
    }
}

/// A reader that hashes what passes through it, for [`InputDigest::reading`].
#[derive(Debug)]
pub struct DigestingReader<'a, R> {
    inner: R,
    all: Sha256,
    one: Sha256,
    digest: &'a mut InputDigest,
}

impl<R: Read> Read for DigestingReader<'_, R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.all.update(&buf[..n]);
        self.one.update(&buf[..n]);
        Ok(n)
    }
}

impl<R: Read> DigestingReader<'_, R> {
    /// Hashes whatever the reader has not yet yielded (a reader stopped early still gets the
    /// whole file's digest), adds the file to the digest and returns the file's own digest.
    ///
    /// # Errors
    /// The inner reader's error.
    pub fn finish(mut self) -> std::io::Result<[u8; 32]> {
        std::io::copy(&mut self, &mut std::io::sink())?;
        let one: [u8; 32] = self.one.finalize().into();
        self.digest.all = self.all;
        self.digest.each.push(one);
        Ok(one)
    }
}

/// The digest of `paths` together (the model's input digest) and of each file alone, in one
/// read of each file.
///
/// # Errors
/// [`CalError::Io`] naming the file that cannot be opened or read.
pub fn digests_of_files(paths: &[PathBuf]) -> Result<Digests, CalError> {
    let mut digest = InputDigest::new();
    for path in paths {
        digest.add_file(path)?;
    }
    Ok(digest.finish())
}

/// The note for validation logs the model `model` (`name` as displayed) was fitted on,
/// `None` otherwise: all of them together have the model's input digest, or (format 6) some
/// have the digest it records of a calibration log, or (older models) one alone has the
/// input digest. A digest of zeros (unknown) matches nothing.
///
/// # Errors
/// As [`digests_of_files`].
pub fn in_sample_note(name: &str, model: &Model<'_>, logs: &[PathBuf]) -> Result<Option<String>, CalError> {
    if model.input_digest() == [0; 32] && model.log_reading().is_none_or(|r| r.log_count() == 0) {
        return Ok(None);
    }
    Ok(in_sample_note_from(name, model, logs, &digests_of_files(logs)?))
}

/// [`in_sample_note`] from the digests of `logs` already taken (`(together, each)`, as
/// [`InputDigest::finish`] gives them).
pub fn in_sample_note_from(
    name: &str,
    model: &Model<'_>,
    logs: &[PathBuf],
    (all, each): &Digests,
) -> Option<String> {
    let digest = model.input_digest();
    if digest != [0; 32] && *all == digest {
        let these = if logs.len() == 1 {
            "this log is the one".to_string()
        } else {
            format!("these {} logs are the ones", logs.len())
        };
        return Some(format!(
            "{these} {name} was fitted on (its input digest matches): the figures are in-sample, \
             not a validation on runs the model did not see"
        ));
    }
    let recorded = LogReadingRecord::of(model).log_digests;
    if recorded.is_empty() {
        // Before format 6 the model keeps one digest: only a log fitted alone is recognised.
        return (digest != [0; 32])
            .then(|| {
                logs.iter().zip(each).find(|(_, d)| **d == digest).map(|(log, _)| in_sample_log(name, log))
            })
            .flatten();
    }
    let fitted: Vec<&PathBuf> = logs
        .iter()
        .zip(each)
        .filter(|(_, d)| recorded.contains(&short_digest(d)))
        .map(|(log, _)| log)
        .collect();
    in_sample_logs(name, &fitted, logs.len(), recorded.len())
}

/// The note for logs among `logs` with the same bytes (`each`: their digests, in order): a
/// copy under another name counts twice, in a fit and its cross-validation as in a
/// validation's overall figure (review13 F3: the same path twice is refused, a copy was not).
pub fn same_logs_note(logs: &[PathBuf], each: &[[u8; 32]]) -> Option<String> {
    let mut groups: Vec<Vec<&PathBuf>> = Vec::new();
    for (k, (log, digest)) in logs.iter().zip(each).enumerate() {
        if each[..k].contains(digest) {
            continue;
        }
        let same: Vec<&PathBuf> =
            logs.iter().zip(each).skip(k + 1).filter(|(_, d)| *d == digest).map(|(l, _)| l).collect();
        if !same.is_empty() {
            groups.push(std::iter::once(log).chain(same).collect());
        }
    }
    let described: Vec<String> = groups
        .iter()
        .map(|g| g.iter().map(|l| l.display().to_string()).collect::<Vec<_>>().join(" = "))
        .collect();
    (!groups.is_empty()).then(|| {
        format!(
            "logs with the same bytes, each counted as a run of its own: {} (a copy under another name? give each \
             run once)",
            described.join("; ")
        )
    })
}

fn in_sample_log(name: &str, log: &Path) -> String {
    format!(
        "{} is the log {name} was fitted on (its input digest matches): its figures are in-sample",
        log.display()
    )
}

/// The note for `fitted`, those of `given` validation logs that are among the `recorded`
/// calibration logs of the model `name`.
fn in_sample_logs(name: &str, fitted: &[&PathBuf], given: usize, recorded: usize) -> Option<String> {
    let shown: Vec<String> = fitted.iter().take(6).map(|p| p.display().to_string()).collect();
    let more = fitted.len().saturating_sub(shown.len());
    let listed = if more > 0 { format!("{} and {more} more", shown.join(", ")) } else { shown.join(", ") };
    let among = if recorded == 1 {
        format!("the log {name} was fitted on (its digest matches)")
    } else {
        format!("among the {recorded} logs {name} was fitted on (their digests match)")
    };
    match fitted.len() {
        0 => None,
        n if n == given => Some(format!(
            "{} {among}: the figures are in-sample, not a validation on runs the model did not see",
            match n {
                1 => format!("{listed} is"),
                2 => "both logs given are".to_string(),
                _ => format!("all {n} logs given are"),
            }
        )),
        n => Some(format!(
            "{listed} ({n} of the {given} logs given) {} {among}: {} in-sample, and the overall figures mix \
             them with the others'; leave {} out for a validation on runs the model did not see",
            if n == 1 { "is" } else { "are" },
            if n == 1 { "its figures are" } else { "their figures are" },
            if n == 1 { "it" } else { "them" },
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blob::{encode, ColumnNames, ModelFile};

    /// A one-axis constant model with `input_digest` and the log digests of `logs` (format 6),
    /// or none (format 4: a model written before them).
    fn model(input_digest: [u8; 32], logs: &[[u8; 32]]) -> Vec<u8> {
        let axis = crate::blob::test_poly_axis(vec![fogtemp_core::PolyTerm {
            temp_power: 0,
            rate_power: 0,
            coefficient_dph: 1.0,
        }]);
        encode(&ModelFile {
            tool_version: String::new(),
            input_digest,
            axes: vec![axis],
            columns: vec![ColumnNames::default()],
            log_time: Default::default(),
            log_reading: LogReadingRecord::of_logs(false, logs),
            input_rates: None,
        })
        .expect("encodes")
    }

    #[test]
    fn the_digest_is_sha256_of_the_files_one_after_another_and_names_in_sample_logs() {
        let dir = tempfile::tempdir().expect("tempdir");
        let (a, b) = (dir.path().join("a.csv"), dir.path().join("b.csv"));
        std::fs::write(&a, b"abc").expect("write");
        std::fs::write(&b, b"").expect("write");
        let (all, each) = digests_of_files(&[a.clone(), b.clone()]).expect("digests");
        // FIPS 180-2's example: SHA-256("abc"); the empty file adds nothing to the whole.
        let abc = "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad";
        let hex = |d: &[u8; 32]| d.iter().map(|b| format!("{b:02x}")).collect::<String>();
        assert_eq!((hex(&all), hex(&each[0])), (abc.to_string(), abc.to_string()));
        assert_eq!(hex(&each[1]), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
        let note = |blob: &[u8], logs: &[PathBuf]| {
            let m = Model::from_bytes(blob).expect("reads");
            in_sample_note("m.fogm", &m, logs).expect("read")
        };
        // A model written before log digests (format 4): the logs together, or one fitted alone.
        let old_both = model(all, &[]);
        assert_eq!(Model::from_bytes(&old_both).expect("reads").format_version(), 4);
        let both = note(&old_both, &[a.clone(), b.clone()]).expect("note");
        assert!(both.starts_with("these 2 logs are the ones m.fogm was fitted on"), "{both}");
        assert_eq!(note(&model(each[1], &[]), &[a.clone(), b.clone()]), Some(in_sample_log("m.fogm", &b)));
        assert_eq!(note(&model([0; 32], &[]), std::slice::from_ref(&a)), None);
        assert_eq!(note(&model([1; 32], &[]), std::slice::from_ref(&a)), None);
        let missing = dir.path().join("missing.csv");
        let m = model([1; 32], &[]);
        let m = Model::from_bytes(&m).expect("reads");
        assert!(matches!(in_sample_note("m.fogm", &m, &[missing]), Err(CalError::Io { .. })));
    }

    #[test]
    fn logs_with_the_same_bytes_are_named_together() {
        let logs: Vec<PathBuf> = ["a.csv", "b.csv", "c.csv", "d.csv"].iter().map(PathBuf::from).collect();
        let each = [[1; 32], [2; 32], [1; 32], [1; 32]];
        assert_eq!(
            same_logs_note(&logs, &each).as_deref(),
            Some(
                "logs with the same bytes, each counted as a run of its own: a.csv = c.csv = d.csv (a copy under \
                 another name? give each run once)"
            )
        );
        assert_eq!(same_logs_note(&logs[..2], &each[..2]), None);
    }

    #[test]
    fn a_model_with_log_digests_names_each_calibration_log_among_the_validation_logs() {
        // Fitted on a and b together; validated on b, c and d: b is named, as 1 of 3.
        let dir = tempfile::tempdir().expect("tempdir");
        let path = |n: &str| dir.path().join(n);
        for (n, text) in [("a.csv", "a"), ("b.csv", "b"), ("c.csv", "c"), ("d.csv", "d")] {
            std::fs::write(path(n), text).expect("write");
        }
        let (together, each) = digests_of_files(&[path("a.csv"), path("b.csv")]).expect("digests");
        let blob = model(together, &each);
        let m = Model::from_bytes(&blob).expect("reads");
        assert_eq!(m.format_version(), 6);
        assert_eq!(m.log_reading().map(|r| r.log_count()), Some(2));
        let note = |logs: &[&str]| {
            let logs: Vec<PathBuf> = logs.iter().map(|n| path(n)).collect();
            in_sample_note("m.fogm", &m, &logs).expect("read")
        };
        let b = path("b.csv").display().to_string();
        assert_eq!(
            note(&["b.csv", "c.csv", "d.csv"]),
            Some(format!(
                "{b} (1 of the 3 logs given) is among the 2 logs m.fogm was fitted on (their digests match): its \
                 figures are in-sample, and the overall figures mix them with the others'; leave it out for a \
                 validation on runs the model did not see"
            ))
        );
        let all_in = note(&["b.csv", "a.csv"]).expect("note");
        assert!(all_in.starts_with("both logs given are among the 2 logs m.fogm was fitted on"), "{all_in}");
        assert_eq!(note(&["b.csv"]).map(|n| n.starts_with(&format!("{b} is among the 2 logs"))), Some(true));
        // The logs in the fit's order have the input digest: said as before.
        let same = note(&["a.csv", "b.csv"]).expect("note");
        assert!(same.starts_with("these 2 logs are the ones m.fogm was fitted on"), "{same}");
        assert_eq!(note(&["c.csv", "d.csv"]), None);
    }
}
