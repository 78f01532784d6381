//! The model's input digest (`docs/model-format.md`: SHA-256 over the calibration logs'
//! bytes, one after another, in the order they were read), and what `validate` says when the
//! logs it is given are the ones a model was fitted on.

use std::io::Read;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use crate::error::CalError;

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

    /// The digest of the files together and of each alone, in the order they were added.
    pub fn finish(self) -> ([u8; 32], Vec<[u8; 32]>) {
        (self.all.finalize().into(), self.each)
    }
}

/// The digest of `paths` together (the model's input digest) and of each file alone, in one
/// read of each file.
///
/// # Errors
/// [`CalError::Io`] naming the file that cannot be opened or read.
pub fn digests_of_files(paths: &[PathBuf]) -> Result<([u8; 32], Vec<[u8; 32]>), CalError> {
    let mut digest = InputDigest::new();
    for path in paths {
        digest.add_file(path)?;
    }
    Ok(digest.finish())
}

/// The note for validation logs the model `model` (as displayed) was fitted on, `None`
/// otherwise: all of them together, or one alone, have the model's input `digest`. Logs
/// fitted together with others are not recognised one by one (the model keeps one digest);
/// a digest of zeros (unknown) matches nothing.
///
/// # Errors
/// As [`digests_of_files`].
pub fn in_sample_note(model: &str, digest: [u8; 32], logs: &[PathBuf]) -> Result<Option<String>, CalError> {
    if digest == [0; 32] {
        return Ok(None);
    }
    Ok(in_sample_note_from(model, digest, logs, &digests_of_files(logs)?))
}

/// [`in_sample_note`] from the digests of `logs` already taken (`(together, each)`, as
/// [`InputDigest::finish`] gives them).
pub fn in_sample_note_from(
    model: &str,
    digest: [u8; 32],
    logs: &[PathBuf],
    (all, each): &([u8; 32], Vec<[u8; 32]>),
) -> Option<String> {
    if digest == [0; 32] {
        return None;
    }
    if *all == digest {
        let these = if logs.len() == 1 {
            "this log is the one".to_string()
        } else {
            format!("these {} logs are the ones", logs.len())
        };
        return Some(format!(
            "{these} {model} was fitted on (its input digest matches): the figures are in-sample, \
             not a validation on runs the model did not see"
        ));
    }
    logs.iter().zip(each).find(|(_, d)| **d == digest).map(|(log, _)| in_sample_log(model, log))
}

fn in_sample_log(model: &str, log: &Path) -> String {
    format!(
        "{} is the log {model} was fitted on (its input digest matches): its figures are in-sample",
        log.display()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

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

        let both = in_sample_note("m.fogm", all, &[a.clone(), b.clone()]).expect("read").expect("note");
        assert!(both.starts_with("these 2 logs are the ones m.fogm was fitted on"), "{both}");
        let one = in_sample_note("m.fogm", each[1], &[a.clone(), b.clone()]).expect("read").expect("note");
        assert_eq!(one, in_sample_log("m.fogm", &b));
        assert_eq!(in_sample_note("m.fogm", [0; 32], std::slice::from_ref(&a)).expect("read"), None);
        assert_eq!(in_sample_note("m.fogm", [1; 32], std::slice::from_ref(&a)).expect("read"), None);
        let missing = dir.path().join("missing.csv");
        assert!(matches!(in_sample_note("m.fogm", [1; 32], &[missing]), Err(CalError::Io { .. })));
    }
}
