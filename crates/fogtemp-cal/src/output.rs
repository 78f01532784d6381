//! Atomic file output: every file the library or the CLI writes goes through a temporary
//! file beside its destination, is flushed and synced, and is renamed into place, so a
//! failure (full disk, crash, bad data half-way) never leaves half a file under the final
//! name. [`stage`] + [`Staged::commit`] serve outputs that must all be written before any
//! of them is moved into place.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::error::CalError;

/// Buffer of the writer handed to the closures (large: simulated logs are gigabytes).
const WRITE_BUFFER_BYTES: usize = 1 << 20;

/// The temporary files of outputs being written or staged, for [`remove_pending_outputs`].
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Registers a temporary file in [`PENDING`] while it lives.
#[derive(Debug)]
struct Pending(PathBuf);

impl Pending {
    fn new(tmp: &Path) -> Self {
        if let Ok(mut pending) = PENDING.lock() {
            pending.push(tmp.to_path_buf());
        }
        Self(tmp.to_path_buf())
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        if let Ok(mut pending) = PENDING.lock() {
            pending.retain(|p| *p != self.0);
        }
    }
}

/// Removes the temporary file of every output still being written or staged: for a signal
/// handler (the CLI's on Ctrl-C), since a process killed by a signal runs no destructor,
/// and an interrupted `compensate` left hundreds of megabytes in a hidden `.fogtemp-*`
/// file. Does not block: when the list is locked (a file is being registered), nothing is
/// removed.
pub fn remove_pending_outputs() {
    if let Ok(pending) = PENDING.try_lock() {
        for tmp in pending.iter() {
            // Best effort: the process is ending.
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// An output written and synced to a temporary file beside its destination; dropping it
/// removes the temporary file, [`Staged::commit`] renames it into place.
/// An output to a device or a named pipe (`/dev/null`, a FIFO) has no temporary file: it
/// was written straight into its destination ([`is_special_file`]).
#[derive(Debug)]
pub struct Staged {
    tmp: Option<(tempfile::NamedTempFile, Pending)>,
    path: PathBuf,
}

impl Staged {
    /// Renames the staged file over its destination (nothing to do for a device or a pipe,
    /// written already).
    ///
    /// # Errors
    /// [`CalError::Output`] if the rename fails (the temporary file is removed).
    pub fn commit(self) -> Result<(), CalError> {
        let Some((tmp, _pending)) = self.tmp else { return Ok(()) };
        let path = self.path;
        tmp.persist(&path).map_err(|e| CalError::Output {
            action: "cannot move the output into place at",
            path,
            source: e.error,
        })?;
        Ok(())
    }

    /// Where the file goes on [`Staged::commit`].
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// The prefix of the temporary files that [`stage`] makes for `path`: `.NAME.fogtemp-`, with
/// NAME cut to its first [`PREFIX_NAME_BYTES`] bytes (at a character boundary), so that the
/// temporary's name (the prefix and 6 random characters) stays within the 255 bytes a file
/// name may have wherever the destination's does (review25a 3: a 245-byte name failed after
/// the whole fit).
pub fn temporary_prefix(path: &Path) -> String {
    let name = path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    if name.len() <= PREFIX_NAME_BYTES {
        return format!(".{name}.fogtemp-");
    }
    // Cut, with a digest of the whole name: two long names that share their first bytes get
    // prefixes of their own, so that neither's temporaries read as the other's leftovers.
    let mut end = PREFIX_NAME_BYTES - 9;
    while !name.is_char_boundary(end) {
        end -= 1;
    }
    let digest = name
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325_u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3));
    format!(".{}~{:08x}.fogtemp-", &name[..end], digest as u32)
}

/// The bytes of a destination's name that its temporary files' names keep: 255 less the
/// 16 that the dots, `fogtemp-` and the 6 random characters take, rounded down.
const PREFIX_NAME_BYTES: usize = 230;

/// Temporary files of `path` already in its folder, with their sizes in bytes, by name: left
/// by a process killed with SIGKILL (no handler runs), or being written by one still running
/// (review24b F9: a 183 MiB hidden file that later runs never mentioned). Not removed here:
/// it may be another process's.
pub fn leftover_temporaries(path: &Path) -> Vec<(PathBuf, u64)> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let prefix = temporary_prefix(path);
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    let mut found: Vec<(PathBuf, u64)> = entries
        .filter_map(Result::ok)
        .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
        .filter_map(|e| Some((e.path(), e.metadata().ok().filter(std::fs::Metadata::is_file)?.len())))
        .collect();
    found.sort();
    found
}

/// Where writing an output puts its bytes ([`destination`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Destination {
    /// A regular file (there or not yet), replaced atomically: a temporary beside it renamed
    /// over it.
    Replace(PathBuf),
    /// A device, a named pipe, a socket or a process's stream (`/dev/stdout`,
    /// `/proc/self/fd/N`), written straight into and appended to: renaming over them replaced
    /// the machine's `/dev/full` (review27a 1), and a file behind `/dev/stdout` lost what the
    /// shell had written to it (review28a 1).
    InPlace(PathBuf),
}

impl Destination {
    /// The path written.
    pub fn path(&self) -> &Path {
        match self {
            Destination::Replace(p) | Destination::InPlace(p) => p,
        }
    }
}

/// Symbolic links followed before giving up, as the kernel's limit.
const MAX_LINK_HOPS: usize = 40;

/// Where writing `path` puts its bytes ([`Destination`]). A symbolic link is followed hop by
/// hop to the file it names, there or not yet, as the shell's `>` follows it: renaming a
/// temporary over the link replaced the link and left its target as it was (review27a 1).
///
/// # Errors
/// [`CalError::Output`] for a loop of links (or more than 40), and for a link in a shared
/// folder (sticky and writable by all, as `/tmp`) that its folder's owner does not own:
/// another user may have planted it to make this process write elsewhere (the kernel's
/// `fs.protected_symlinks` refuses those to the shell; review28a 5).
pub fn destination(path: &Path) -> Result<Destination, CalError> {
    if is_process_stream(path) {
        return Ok(Destination::InPlace(path.to_path_buf()));
    }
    let mut current = path.to_path_buf();
    for _ in 0..MAX_LINK_HOPS {
        let is_link = std::fs::symlink_metadata(&current).is_ok_and(|m| m.file_type().is_symlink());
        if !is_link {
            return Ok(if is_special_file(&current) {
                Destination::InPlace(current)
            } else {
                Destination::Replace(current)
            });
        }
        refuse_planted_link(&current)?;
        let target = std::fs::read_link(&current).map_err(|source| CalError::Output {
            action: "cannot read the symbolic link",
            path: current.clone(),
            source,
        })?;
        current = match current.parent() {
            Some(dir) if target.is_relative() => dir.join(target),
            _ => target,
        };
    }
    Err(CalError::Output {
        action: "cannot write",
        path: path.to_path_buf(),
        source: std::io::Error::other("too many levels of symbolic links (a loop?)"),
    })
}

/// Whether `path` names a process's stream or descriptor (`/dev/stdout`, `/dev/stderr`,
/// `/dev/fd/N`, `/proc/...`): whatever it points at, it is written in place.
fn is_process_stream(path: &Path) -> bool {
    ["/dev/stdout", "/dev/stderr"].iter().any(|s| path == Path::new(s))
        || path.starts_with("/dev/fd")
        || path.starts_with("/proc")
}

/// Refuses to follow a symbolic link in a folder that is sticky and writable by all unless
/// the folder's owner owns it (the rule of the kernel's `fs.protected_symlinks`, less the
/// follower's own uid, which std does not give).
fn refuse_planted_link(link: &Path) -> Result<(), CalError> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let dir = match link.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        let (Ok(dir_meta), Ok(link_meta)) = (std::fs::metadata(dir), std::fs::symlink_metadata(link)) else {
            return Ok(());
        };
        let shared = dir_meta.mode() & 0o1002 == 0o1002;
        if shared && link_meta.uid() != dir_meta.uid() {
            return Err(CalError::Output {
                action: "will not follow the symbolic link",
                path: link.to_path_buf(),
                source: std::io::Error::other(format!(
                    "it lies in {}, a folder shared by all users, and another user owns it: give the path of the file it names",
                    dir.display()
                )),
            });
        }
    }
    #[cfg(not(unix))]
    let _ = link;
    Ok(())
}

/// Whether `path` is there and neither a regular file nor a folder: a device (`/dev/null`,
/// `/dev/full`, a terminal), a named pipe or a socket (written in place: [`Destination`]).
/// A named pipe with no reader blocks the write until one comes, as the shell's `>` does.
pub fn is_special_file(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// Checks before any long work that the file `path` can be written where it is named: not a
/// folder, its folder exists and a file can be made in it (with the prefix its temporary will
/// have; the check's file is removed at once). A device or a pipe is fine as it is. For the
/// command line and Python alike (review27a 11: Python's `fit(out=FOLDER)` found the folder
/// after the fit and lost the model).
///
/// # Errors
/// [`CalError::Output`] naming the path and what is wrong.
pub fn check_output_file(path: &Path) -> Result<(), CalError> {
    let out = match destination(path)? {
        Destination::InPlace(_) => return Ok(()),
        Destination::Replace(out) => out,
    };
    let out = &out;
    let refuse = |text: String| CalError::Output {
        action: "cannot write",
        path: path.to_path_buf(),
        source: std::io::Error::other(text),
    };
    if out.is_dir() {
        return Err(refuse("is a folder; give the path of the file to write".into()));
    }
    let folder = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if folder.exists() && !folder.is_dir() {
        return Err(refuse(format!("{} is a file, not a folder", folder.display())));
    }
    if !folder.is_dir() {
        return Err(refuse(format!("the folder {} does not exist", folder.display())));
    }
    tempfile::Builder::new().prefix(&temporary_prefix(out)).tempfile_in(folder).map(drop).map_err(|source| {
        CalError::Output { action: "cannot create a temporary file in", path: folder.to_path_buf(), source }
    })
}

/// Writes `path`'s content with `write` into a synced temporary file in the same folder
/// (mode 0666 less the umask, like a new file), ready to be moved into place. The
/// destination is the file a symbolic link names ([`destination`]); a device or a named
/// pipe is written straight into at once ([`is_special_file`]).
///
/// # Errors
/// [`CalError::Output`] naming the folder or file and what failed; the temporary file is
/// removed.
pub fn stage(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<Staged, CalError> {
    let path = &match destination(path)? {
        Destination::InPlace(path) => {
            write_in_place(&path, write)?;
            return Ok(Staged { tmp: None, path });
        }
        Destination::Replace(path) => path,
    };
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    // A write-protected destination is refused, as the shell's `>` refuses it: the rename
    // below would replace it regardless (review23b F5: a released model, chmod 444, was
    // replaced without a word).
    if std::fs::metadata(path).is_ok_and(|m| m.is_file() && m.permissions().readonly()) {
        return Err(CalError::Output {
            action: "will not replace the write-protected file",
            path: path.to_path_buf(),
            source: std::io::Error::new(
                std::io::ErrorKind::PermissionDenied,
                "it is read-only: make it writable or remove it first to replace it",
            ),
        });
    }
    let mut builder = tempfile::Builder::new();
    // Named after the destination, so that a file left by a killed process (SIGKILL runs no
    // handler) says whose it was: `.run-comp.csv.fogtemp-XXXXXX`.
    let prefix = temporary_prefix(path);
    builder.prefix(&prefix);
    // The usual mode of a new file (0666 less the umask), not tempfile's private 0600.
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    let mut tmp = builder.tempfile_in(&dir).map_err(|source| CalError::Output {
        action: "cannot create a temporary file in",
        path: dir.clone(),
        source,
    })?;
    let pending = Pending::new(tmp.path());
    let failed = |action: &'static str| {
        let path = path.to_path_buf();
        move |source| CalError::Output { action, path, source }
    };
    {
        let mut buffered = std::io::BufWriter::with_capacity(WRITE_BUFFER_BYTES, tmp.as_file_mut());
        write(&mut buffered).map_err(failed("writing"))?;
        buffered.flush().map_err(failed("writing"))?;
    }
    tmp.as_file().sync_all().map_err(failed("syncing"))?;
    Ok(Staged { tmp: Some((tmp, pending)), path: path.to_path_buf() })
}

/// Writes into a device, a named pipe or a process's stream as it is, appending (no
/// temporary, no sync: `/dev/null` cannot be synced, and a pipe's reader has the bytes).
fn write_in_place(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<(), CalError> {
    let failed = |action: &'static str| {
        let path = path.to_path_buf();
        move |source| CalError::Output { action, path, source }
    };
    let file = std::fs::OpenOptions::new().append(true).open(path).map_err(failed("cannot open"))?;
    let mut buffered = std::io::BufWriter::with_capacity(WRITE_BUFFER_BYTES, file);
    write(&mut buffered).map_err(failed("writing"))?;
    buffered.flush().map_err(failed("writing"))
}

/// Writes `path` atomically: [`stage`] then [`Staged::commit`]; inside [`all_or_nothing`],
/// the commit waits for the end of the scope.
///
/// # Errors
/// [`CalError::Output`] naming the file and what failed; nothing is left under `path`'s
/// name unless the whole file was written.
pub fn write_file_atomic(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<(), CalError> {
    let staged = stage(path, write)?;
    // Held back by an open scope, or committed now.
    let unheld = DEFERRED.with(|d| match d.borrow_mut().as_mut() {
        Some(scope) => {
            scope.staged.push(staged);
            None
        }
        None => Some(staged),
    });
    unheld.map_or(Ok(()), Staged::commit)
}

/// What an [`all_or_nothing`] scope holds back until its end: staged files (in order: a
/// later one of the same path wins) and files to remove.
#[derive(Debug, Default)]
struct Deferred {
    staged: Vec<Staged>,
    removals: Vec<PathBuf>,
}

thread_local! {
    /// The open [`all_or_nothing`] scope of this thread, if any.
    static DEFERRED: std::cell::RefCell<Option<Deferred>> = const { std::cell::RefCell::new(None) };
}

/// Runs `work`, holding back every file it writes with [`write_file_atomic`] (and removes
/// with [`remove_file_deferred`]) on this thread until it has succeeded, then moves them all
/// into place; on an error nothing is moved and the staged files are removed. For a report
/// folder: written file by file, a full disk or an interrupt left new figures beside an old
/// `report.md` (review24b F4). Renaming the staged files is quick, so an interrupt can only
/// mix the two reports in that short window. A scope inside a scope joins the outer one.
/// Files read while the scope is open should be read with [`read_current`].
///
/// # Errors
/// What `work` returns, or [`CalError::Output`] for a rename or removal that fails.
pub fn all_or_nothing<T, E: From<CalError>>(work: impl FnOnce() -> Result<T, E>) -> Result<T, E> {
    if DEFERRED.with(|d| d.borrow().is_some()) {
        return work();
    }
    DEFERRED.with(|d| *d.borrow_mut() = Some(Deferred::default()));
    // Closes the scope however `work` ends, a panic included: a scope left open would hold
    // back every later write on this thread (a Python session survives a panic; review25a 11).
    let _close = CloseScope;
    let result = work();
    let deferred = DEFERRED.with(|d| d.borrow_mut().take()).unwrap_or_default();
    let value = result?;
    // Everything that would stop a rename or a removal half way is looked for before the
    // first one, so that a failure leaves the old files as they were (review25a 1: a folder
    // in a figure's place was found after the report's text had been replaced).
    let in_the_way =
        deferred.staged.iter().map(Staged::path).chain(deferred.removals.iter().map(PathBuf::as_path));
    for path in in_the_way {
        if path.is_dir() {
            let source =
                std::io::Error::new(std::io::ErrorKind::IsADirectory, "a folder is in the file's place");
            return Err(
                CalError::Output { action: "cannot replace", path: path.to_path_buf(), source }.into()
            );
        }
    }
    for staged in deferred.staged {
        staged.commit()?;
    }
    for path in deferred.removals {
        match std::fs::remove_file(&path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(CalError::Output { action: "cannot remove", path, source: e }.into());
            }
            _ => {}
        }
    }
    Ok(value)
}

/// Closes this thread's [`all_or_nothing`] scope when dropped (its staged files are removed
/// with it).
struct CloseScope;

impl Drop for CloseScope {
    fn drop(&mut self) {
        DEFERRED.with(|d| d.borrow_mut().take());
    }
}

/// Removes `path` now, or at the end of an open [`all_or_nothing`] scope.
///
/// # Errors
/// The I/O error of a removal done now.
pub fn remove_file_deferred(path: &Path) -> std::io::Result<()> {
    let deferred =
        DEFERRED.with(|d| d.borrow_mut().as_mut().map(|scope| scope.removals.push(path.to_path_buf())));
    match deferred {
        Some(()) => Ok(()),
        None => std::fs::remove_file(path),
    }
}

/// The text of `path` as it will be: the last version staged in this thread's open
/// [`all_or_nothing`] scope, else the file itself.
///
/// # Errors
/// The I/O error of the read.
pub fn read_current(path: &Path) -> std::io::Result<String> {
    // Staged under the file a link names (review28a 2).
    let staged_at = destination(path).map_or_else(|_| path.to_path_buf(), |d| d.path().to_path_buf());
    let staged = DEFERRED.with(|d| {
        d.borrow().as_ref().and_then(|scope| {
            scope
                .staged
                .iter()
                .rev()
                .find(|s| s.path == staged_at)
                .and_then(|s| Some(s.tmp.as_ref()?.0.path().to_path_buf()))
        })
    });
    std::fs::read_to_string(staged.as_deref().unwrap_or(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A folder in the place of one of a scope's files is found before anything moves: the
    /// other files keep their old text (review25a 1); a panic inside a scope closes it, so
    /// later writes on the thread are not held back.
    #[test]
    fn a_folder_in_the_way_moves_nothing_and_a_panic_closes_the_scope() {
        let dir = tempfile::tempdir().expect("temp dir");
        let (text, figure) = (dir.path().join("report.md"), dir.path().join("figure.svg"));
        std::fs::write(&text, b"old").expect("write");
        std::fs::create_dir(&figure).expect("mkdir");
        let failed: Result<(), CalError> = all_or_nothing(|| {
            write_file_atomic(&text, |w| w.write_all(b"new"))?;
            write_file_atomic(&figure, |w| w.write_all(b"<svg/>"))
        });
        let err = failed.expect_err("a folder is in the figure's place");
        assert!(err.to_string().contains("cannot replace"), "{err}");
        assert_eq!(std::fs::read_to_string(&text).expect("read"), "old");
        let names = std::fs::read_dir(dir.path()).expect("list").count();
        assert_eq!(names, 2, "no temporary file left");
        let panicked = std::panic::catch_unwind(|| {
            let _: Result<(), CalError> = all_or_nothing(|| {
                write_file_atomic(&text, |w| w.write_all(b"half"))?;
                panic!("a bug inside the scope")
            });
        });
        assert!(panicked.is_err());
        write_file_atomic(&text, |w| w.write_all(b"after")).expect("write");
        assert_eq!(std::fs::read_to_string(&text).expect("read"), "after", "written at once, no scope open");
    }

    /// Inside a scope nothing moves until its end: a failure replaces none of the old files
    /// (and removes none), a success all of them; `read_current` sees the staged text.
    #[test]
    fn a_scope_replaces_all_its_files_or_none() {
        let dir = tempfile::tempdir().expect("temp dir");
        let (a, b, stale) = (dir.path().join("a.md"), dir.path().join("b.svg"), dir.path().join("old.svg"));
        for path in [&a, &b, &stale] {
            std::fs::write(path, b"old").expect("write");
        }
        let failed: Result<(), CalError> = all_or_nothing(|| {
            write_file_atomic(&a, |w| w.write_all(b"new a"))?;
            assert_eq!(read_current(&a).expect("reads"), "new a", "the staged text");
            assert_eq!(std::fs::read_to_string(&a).expect("reads"), "old", "not moved yet");
            remove_file_deferred(&stale).expect("deferred");
            write_file_atomic(&b, |_| Err(std::io::Error::other("disk full")))
        });
        assert!(failed.is_err());
        for path in [&a, &b, &stale] {
            assert_eq!(std::fs::read_to_string(path).expect("kept"), "old", "{}", path.display());
        }
        let files = || std::fs::read_dir(dir.path()).expect("lists").count();
        assert_eq!(files(), 3, "no temporary file left");
        all_or_nothing(|| -> Result<(), CalError> {
            write_file_atomic(&a, |w| w.write_all(b"new a"))?;
            write_file_atomic(&a, |w| w.write_all(b"newer a"))?;
            remove_file_deferred(&stale).expect("deferred");
            write_file_atomic(&b, |w| w.write_all(b"new b"))
        })
        .expect("writes");
        assert_eq!(std::fs::read_to_string(&a).expect("a"), "newer a", "the last version wins");
        assert_eq!(std::fs::read_to_string(&b).expect("b"), "new b");
        assert!(!stale.exists());
        assert_eq!(files(), 2);
    }

    /// A file named like `out.txt`'s temporary files is found, with its size; others are not.
    #[test]
    fn leftover_temporaries_are_found_by_their_destination() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("out.txt");
        std::fs::write(dir.path().join(".out.txt.fogtemp-AbC123"), b"12345").expect("write");
        std::fs::write(dir.path().join(".other.txt.fogtemp-AbC123"), b"1").expect("write");
        std::fs::write(&path, b"done").expect("write");
        let found = leftover_temporaries(&path);
        assert_eq!(found, vec![(dir.path().join(".out.txt.fogtemp-AbC123"), 5)]);
        write_file_atomic(&path, |w| w.write_all(b"new")).expect("writes");
        assert_eq!(leftover_temporaries(&path).len(), 1, "a write leaves no file of its own");
    }

    #[test]
    fn a_failing_writer_leaves_nothing_and_a_good_one_replaces_the_file() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("out.txt");
        std::fs::write(&path, "old").expect("seed file");
        let err = write_file_atomic(&path, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("disk full"))
        })
        .expect_err("the writer failed");
        assert!(err.to_string().contains("writing") && err.to_string().contains("disk full"), "{err}");
        assert_eq!(std::fs::read_to_string(&path).expect("read"), "old");
        let names: Vec<String> = std::fs::read_dir(dir.path())
            .expect("list")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["out.txt"], "no temporary file left");
        write_file_atomic(&path, |w| w.write_all(b"new")).expect("write");
        assert_eq!(std::fs::read_to_string(&path).expect("read"), "new");
    }

    /// A destination that is a folder fails at the rename; the temporary file is removed and
    /// the folder untouched (the commands check for this before their work; this is the
    /// guard behind that check).
    #[test]
    fn a_failed_rename_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().expect("temp dir");
        let taken = dir.path().join("taken");
        std::fs::create_dir(&taken).expect("mkdir");
        let err = write_file_atomic(&taken, |w| w.write_all(b"x")).expect_err("a folder is in the way");
        assert!(err.to_string().contains("cannot move the output into place"), "{err}");
        let names: Vec<String> = std::fs::read_dir(dir.path())
            .expect("list")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["taken"], "no temporary file left");
        assert!(taken.is_dir() && std::fs::read_dir(&taken).expect("list").next().is_none());
    }

    /// A write-protected destination is refused and kept (review23b F5); a staged file is
    /// named after its destination, so a leftover says whose it was.
    #[test]
    fn a_write_protected_file_is_kept_and_staged_files_name_their_destination() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("released.fogm");
        std::fs::write(&path, "old").expect("seed file");
        let mut permissions = std::fs::metadata(&path).expect("metadata").permissions();
        permissions.set_readonly(true);
        std::fs::set_permissions(&path, permissions).expect("chmod");
        let err = write_file_atomic(&path, |w| w.write_all(b"new")).expect_err("write-protected");
        assert!(err.to_string().contains("will not replace the write-protected file"), "{err}");
        assert_eq!(std::fs::read_to_string(&path).expect("read"), "old");
        let staged = stage(&dir.path().join("run-comp.csv"), |w| w.write_all(b"x")).expect("stage");
        let names: Vec<String> = std::fs::read_dir(dir.path())
            .expect("list")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .filter(|n| n != "released.fogm")
            .collect();
        assert!(names.len() == 1 && names[0].starts_with(".run-comp.csv.fogtemp-"), "{names:?}");
        // A destination name near the 255-byte limit (3-byte characters): the temporary's
        // name is cut to fit and the file is written.
        let long = dir.path().join(format!("{}.fogm", "\u{6a21}".repeat(83)));
        assert_eq!(long.file_name().map(|n| n.len()), Some(254));
        let prefix = temporary_prefix(&long);
        assert!(prefix.len() + 6 <= 255 && prefix.ends_with(".fogtemp-"), "{}", prefix.len());
        write_file_atomic(&long, |w| w.write_all(b"m")).expect("a 254-byte name is written");
        assert_eq!(std::fs::read(&long).expect("read"), b"m");
        let sibling = dir.path().join(format!("{}.fogm", "\u{6a21}".repeat(82) + "x"));
        assert_ne!(
            temporary_prefix(&sibling),
            prefix,
            "names that differ past the cut keep their own prefixes"
        );
        drop(staged);
    }

    #[test]
    fn a_missing_folder_is_named() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("no/such/out.txt");
        let err = write_file_atomic(&path, |w| w.write_all(b"x")).expect_err("no folder");
        assert!(err.to_string().contains("cannot create a temporary file in"), "{err}");
        assert!(err.to_string().contains("no/such"), "{err}");
    }

    /// Review27a 1: a temporary renamed over a symbolic link replaced the link and left its
    /// target as it was. Oracle: the link stays a link, and its target holds the new bytes.
    #[cfg(unix)]
    #[test]
    fn a_symbolic_link_is_written_through() {
        let dir = tempfile::tempdir().expect("temp dir");
        let target = dir.path().join("model-v3.fogm");
        let link = dir.path().join("current.fogm");
        std::fs::write(&target, b"old").expect("seed file");
        std::os::unix::fs::symlink("model-v3.fogm", &link).expect("link");
        write_file_atomic(&link, |w| w.write_all(b"new")).expect("writes");
        assert!(std::fs::symlink_metadata(&link).expect("link").file_type().is_symlink(), "the link is kept");
        assert_eq!(std::fs::read(&target).expect("target"), b"new");
        // A link to a file not there yet makes it.
        let dangling = dir.path().join("next.fogm");
        std::os::unix::fs::symlink("model-v4.fogm", &dangling).expect("link");
        write_file_atomic(&dangling, |w| w.write_all(b"v4")).expect("writes");
        assert_eq!(std::fs::read(dir.path().join("model-v4.fogm")).expect("made"), b"v4");
    }

    /// Review27a 1: a temporary renamed over a device or a named pipe replaced it with a
    /// regular file (the machine's /dev/full). A named pipe is written straight into. Oracle:
    /// it stays a pipe, and its reader gets the bytes.
    #[cfg(unix)]
    #[test]
    fn a_named_pipe_is_written_into_not_replaced() {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().expect("temp dir");
        let fifo = dir.path().join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            eprintln!("SKIPPED: mkfifo is not available here");
            return;
        }
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read(fifo).expect("reads the pipe"))
        };
        assert!(is_special_file(&fifo));
        write_file_atomic(&fifo, |w| w.write_all(b"through the pipe")).expect("writes");
        // Before joining the reader: a rename over the pipe would leave it waiting for ever.
        assert!(std::fs::metadata(&fifo).expect("there").file_type().is_fifo(), "still a pipe");
        assert_eq!(reader.join().expect("reader"), b"through the pipe");
        assert!(leftover_temporaries(&fifo).is_empty());
    }

    /// Review28a 4: a loop of links turned one of them into a regular file, and a chain of
    /// links to a file not there yet replaced the middle link. Oracle: the shell's `>`.
    #[cfg(unix)]
    #[test]
    fn links_are_followed_to_the_end_and_a_loop_is_refused() {
        let dir = tempfile::tempdir().expect("temp dir");
        let (a, b) = (dir.path().join("a"), dir.path().join("b"));
        std::os::unix::fs::symlink("b", &a).expect("link");
        std::os::unix::fs::symlink("a", &b).expect("link");
        let err = write_file_atomic(&a, |w| w.write_all(b"x")).expect_err("a loop");
        assert!(err.to_string().contains("too many levels of symbolic links"), "{err}");
        assert!(std::fs::symlink_metadata(&b).expect("b").file_type().is_symlink(), "b is still a link");
        let (l1, l2) = (dir.path().join("l1"), dir.path().join("l2"));
        std::os::unix::fs::symlink("l2", &l1).expect("link");
        std::os::unix::fs::symlink("final.csv", &l2).expect("link");
        write_file_atomic(&l1, |w| w.write_all(b"end")).expect("writes");
        assert!(std::fs::symlink_metadata(&l2).expect("l2").file_type().is_symlink(), "l2 is still a link");
        assert_eq!(std::fs::read(dir.path().join("final.csv")).expect("made"), b"end");
    }

    /// Review28a 1: `/dev/stdout` (and `/proc/self/fd/N`) are written in place, appended to,
    /// whatever file they stand for; a path that merely lies under `/dev` is not.
    #[test]
    fn process_streams_are_written_in_place() {
        for stream in ["/dev/stdout", "/dev/stderr", "/dev/fd/1", "/proc/self/fd/2"] {
            assert_eq!(
                destination(Path::new(stream)).expect("a destination"),
                Destination::InPlace(PathBuf::from(stream)),
                "{stream}"
            );
        }
        let file = Path::new("/dev/shm/fogtemp-no-such-file.csv");
        assert_eq!(destination(file).expect("a destination"), Destination::Replace(file.to_path_buf()));
    }

    /// Review28a 5: a link in a folder shared by all (sticky, as /tmp) that another user owns
    /// is not followed (the kernel's `fs.protected_symlinks` rule). Needs root to give the link
    /// to another user; skipped otherwise.
    #[cfg(unix)]
    #[test]
    fn a_link_planted_in_a_shared_folder_is_not_followed() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().expect("temp dir");
        let shared = dir.path().join("shared");
        std::fs::create_dir(&shared).expect("mkdir");
        std::fs::set_permissions(&shared, std::fs::Permissions::from_mode(0o1777)).expect("chmod");
        let victim = dir.path().join("victim.txt");
        std::fs::write(&victim, b"keep").expect("seed");
        let link = shared.join("out.csv");
        std::os::unix::fs::symlink(&victim, &link).expect("link");
        if std::os::unix::fs::lchown(&link, Some(65534), Some(65534)).is_err() {
            eprintln!("SKIPPED: giving the link to another user needs root");
            return;
        }
        let err = write_file_atomic(&link, |w| w.write_all(b"x")).expect_err("refused");
        assert!(err.to_string().contains("will not follow the symbolic link"), "{err}");
        assert_eq!(std::fs::read(&victim).expect("victim"), b"keep");
    }
}
