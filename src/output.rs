//! Output files that appear all together or not at all. Every file of a run is written under
//! a temporary name unique to the run; at commit, under a lock shared by all runs writing into
//! the same directory, every destination is checked and then all are renamed into place (and
//! files the run no longer produces are removed), so that concurrent runs on one prefix leave
//! one run's whole set. An uncommitted set is removed.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("cannot write {path}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("cannot write {path}: {message}")]
    Other { path: String, message: String },
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> OutputError + '_ {
    move |source| OutputError::Io {
        path: path.display().to_string(),
        source,
    }
}

fn other(path: &Path, message: impl Into<String>) -> OutputError {
    OutputError::Other {
        path: path.display().to_string(),
        message: message.into(),
    }
}

/// Writes an NPY array of `shape` (row-major) to `path`.
pub fn save_npy<T: npyz::AutoSerialize + Copy>(
    path: &Path,
    shape: &[u64],
    data: &[T],
) -> std::io::Result<()> {
    write_npy(std::io::BufWriter::new(create(path)?), shape, data)
}

/// The bytes of the NPY file [`save_npy`] writes (the Python package's arrays).
pub fn npy_bytes<T: npyz::AutoSerialize + Copy>(shape: &[u64], data: &[T]) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    write_npy(&mut out, shape, data).expect("writing to memory cannot fail");
    out.into_inner()
}

fn write_npy<T: npyz::AutoSerialize + Copy>(
    f: impl std::io::Write,
    shape: &[u64],
    data: &[T],
) -> std::io::Result<()> {
    use npyz::WriterBuilder;
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(shape)
        .writer(f)
        .begin_nd()?;
    w.extend(data.iter().copied())?;
    w.finish()
}

/// A set of output files committed together.
#[derive(Default)]
pub struct Staged {
    /// (temporary, final) paths.
    files: Vec<(PathBuf, PathBuf)>,
    /// Files of an earlier run that this set does not produce.
    stale: Vec<PathBuf>,
    /// The set's JSON, which lists the set's files ([`Staged::manifest`]).
    manifest: Option<PathBuf>,
    /// Files of this run committed by a set of their own, listed in this one's manifest.
    listed: Vec<PathBuf>,
    /// Files the set was computed from, with their fingerprints then: the commit goes ahead
    /// only if each is still so, checked under the commit's lock.
    read: Vec<(PathBuf, String)>,
}

/// The part of a set's JSON that lists its files.
#[derive(serde::Deserialize)]
struct Manifest {
    #[serde(default)]
    files: Vec<String>,
    /// Each file's fingerprint as rattle wrote it ([`fingerprint`]): what proves a file is
    /// still the one the set wrote.
    #[serde(default)]
    file_sums: std::collections::BTreeMap<String, String>,
}

/// The fingerprint of a file whose contents are `bytes` ([`fingerprint`]).
pub fn fingerprint_of(bytes: &[u8]) -> String {
    format!("{}:{:08x}", bytes.len(), crc32fast::hash(bytes))
}

/// The fingerprints a set's JSON `text` recorded at its commit, by file name.
pub fn recorded_sums(text: &[u8]) -> std::collections::BTreeMap<String, String> {
    serde_json::from_slice::<Manifest>(text)
        .map(|m| m.file_sums)
        .unwrap_or_default()
}

/// A file's size and CRC-32, `SIZE:CRC` (hex); None where it cannot be read.
fn fingerprint(path: &Path) -> Option<String> {
    use std::io::Read;
    let mut f = std::fs::File::open(path).ok()?;
    let mut h = crc32fast::Hasher::new();
    let mut buf = vec![0u8; 1 << 16];
    let mut size = 0u64;
    loop {
        let n = f.read(&mut buf).ok()?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
        size += n as u64;
    }
    Some(format!("{size}:{:08x}", h.finalize()))
}

/// The files of the set whose JSON is `json` that are still as that set wrote them: listed in
/// its `files`, plain names beginning with the JSON's own stem (`x.csv`, `x-class.npy` for
/// `x.json`, so a JSON cannot name files elsewhere), and with the size and CRC the set recorded
/// in `file_sums` at its commit. A JSON rattle did not write (no sums), a file written since by
/// anyone else, or one another set has replaced, is never among them.
fn listed_by(json: &Path) -> Vec<PathBuf> {
    let is_file = |p: &Path| std::fs::symlink_metadata(p).is_ok_and(|m| m.is_file());
    if !is_file(json) {
        return Vec::new();
    }
    let Ok(f) = std::fs::File::open(json) else {
        return Vec::new();
    };
    let Ok(m) = serde_json::from_reader::<_, Manifest>(std::io::BufReader::new(f)) else {
        return Vec::new();
    };
    let (Some(stem), dir) = (
        json.file_stem().and_then(|s| s.to_str()),
        json.parent().unwrap_or(Path::new("")),
    ) else {
        return Vec::new();
    };
    m.files
        .iter()
        .filter(|n| Path::new(n).file_name().and_then(|f| f.to_str()) == Some(n.as_str()))
        .filter(|n| n.starts_with(&format!("{stem}.")) || n.starts_with(&format!("{stem}-")))
        .map(|n| (dir.join(n), m.file_sums.get(n)))
        .filter(|(p, sum)| is_file(p) && sum.is_some() && fingerprint(p).as_ref() == *sum)
        .map(|(p, _)| p)
        .collect()
}

/// The files of the set whose JSON is `json` that are still as it wrote them (see
/// `listed_by`): what replacing or removing that set may remove.
pub fn set_files(json: &Path) -> Vec<PathBuf> {
    listed_by(json)
}

/// Refuses, before computing, a file a set would write (`fig-compare.png` of `map --compare
/// --out fig`) that another set at its own prefix (`fig-compare.json`) still owns.
pub fn check_not_owned(file: &Path) -> Result<(), OutputError> {
    let Some(stem) = file.file_stem() else {
        return Ok(());
    };
    let json = file.with_file_name(format!("{}.json", stem.to_string_lossy()));
    if json != file && listed_by(&json).iter().any(|f| f == file) {
        return Err(other(
            file,
            format!(
                "it belongs to the set of {} (written by an earlier run); choose another prefix",
                json.display()
            ),
        ));
    }
    Ok(())
}

/// Refuses a set at `prefix` that a command names after another set's prefix (a map's
/// boundaries at `PREFIX-boundaries` beside its map at `PREFIX`) where `PREFIX.json` there is
/// the JSON of a set of other files (a map written at that prefix): replacing it would remove
/// that set's files, which the user did not name. The set at `prefix` writes only `exts`.
pub fn check_implied_prefix(prefix: &Path, exts: &[&str]) -> Result<(), OutputError> {
    let json = with_ext(prefix, "json");
    let ours: Vec<PathBuf> = exts.iter().map(|x| with_ext(prefix, x)).collect();
    if let Some(f) = listed_by(&json).into_iter().find(|f| !ours.contains(f)) {
        return Err(other(
            &json,
            format!(
                "it is the JSON of another set (it lists {}, written by an earlier run), which \
                 this set would replace; choose another prefix",
                f.display()
            ),
        ));
    }
    Ok(())
}

/// A file of another set that a set at `prefix` would write over: one that the JSON of a
/// shorter prefix (`fig.json` for `fig-compare`) lists as its own, still as it wrote it, and
/// whose name begins with `prefix`'s (`fig-compare.png`). Returns the file and that JSON.
fn owned_by_another_set(prefix: &Path) -> Option<(PathBuf, PathBuf)> {
    let name = prefix.file_name()?.to_str()?;
    let dir = prefix.parent().unwrap_or(Path::new(""));
    let mut stem = name;
    while let Some((head, _)) = stem.rsplit_once('-') {
        stem = head;
        let json = dir.join(format!("{stem}.json"));
        if let Some(f) = listed_by(&json).into_iter().find(|f| {
            f.file_name().and_then(|n| n.to_str()).is_some_and(|n| {
                n.starts_with(&format!("{name}.")) || n.starts_with(&format!("{name}-"))
            })
        }) {
            return Some((f, json));
        }
    }
    None
}

/// Distinguishes the sets of one process.
static SET: AtomicU64 = AtomicU64::new(0);

/// Held while a set is renamed into place. An interrupt handler takes it before it ends the
/// process ([`interrupt_guard`]), so an interrupt during a commit waits for the whole set to be
/// in place: an interrupted run never leaves its set mixed with an older run's (its `.partial`
/// files, if any, are removed by the next commit on the prefix).
static RENAMING: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The temporary files of every set of this process not yet committed or dropped: what an
/// interrupt removes before the process ends ([`interrupt_guard`]).
static PENDING: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn pending() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    PENDING.lock().unwrap_or_else(|e| e.into_inner())
}

/// Set by an interrupt once it has removed the pending files: no temporary file is created
/// after it ([`create`]).
static ENDING: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Creates a staged temporary file. Creation and an interrupt's removal exclude each other
/// (both under [`PENDING`]'s lock), and after an interrupt no file is created: the thread waits
/// for the process to end. So an interrupted run leaves no `.partial`, even one being created
/// at that instant; what a writer writes after the removal goes to an unlinked file.
///
/// A staged name is opened only as the file [`Staged::path`] created there itself (exclusively,
/// `O_EXCL`), never through a link (`O_NOFOLLOW`), and only while it is that file (a regular
/// file with one link): another user who can write to the output folder cannot have a set
/// written through a link planted at the name, nor into a file put in its place. A name that is
/// not staged (a figure an example writes) is created or replaced, never through a link.
pub fn create(tmp: &Path) -> std::io::Result<std::fs::File> {
    let guard = pending();
    if ENDING.load(Ordering::SeqCst) {
        drop(guard);
        loop {
            std::thread::park();
        }
    }
    let ours = created().iter().any(|p| p == tmp);
    drop(guard);
    match ours {
        true => open_own(tmp, true),
        false => plain(tmp),
    }
}

/// A file written outside a set (an example's figure): created or replaced, never through a
/// link at its name.
fn plain(path: &Path) -> std::io::Result<std::fs::File> {
    let mut o = std::fs::OpenOptions::new();
    o.write(true).create(true).truncate(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::custom_flags(&mut o, libc::O_NOFOLLOW);
    o.open(path)
}

/// The staged files [`Staged::path`] created, which [`create`] may open.
static CREATED: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn created() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    CREATED.lock().unwrap_or_else(|e| e.into_inner())
}

/// Creates `path` for writing only if no file, directory or link has that name (`O_EXCL`:
/// a link, even a dangling one, is never followed).
fn exclusive(path: &Path) -> std::io::Result<std::fs::File> {
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
}

/// Opens a file this process created (truncated where `truncate`), refusing a link at its
/// name (`O_NOFOLLOW`) and a file that is not the one created (not regular, or with another
/// link to it).
fn open_own(path: &Path, truncate: bool) -> std::io::Result<std::fs::File> {
    let mut o = std::fs::OpenOptions::new();
    // Truncated only once it is known to be the file created (O_TRUNC would empty another).
    o.read(true).write(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::custom_flags(&mut o, libc::O_NOFOLLOW);
    let f = o.open(path).map_err(|e| match e.raw_os_error() {
        #[cfg(unix)]
        Some(libc::ELOOP) => std::io::Error::other(
            "a symbolic link was put in the place of the file rattle staged: not written \
             through",
        ),
        _ => e,
    })?;
    let m = f.metadata()?;
    if !m.is_file() || !single(&m) {
        return Err(std::io::Error::other(
            "another file was put in the place of the file rattle staged: not written",
        ));
    }
    if truncate {
        f.set_len(0)?;
    }
    Ok(f)
}

/// Whether a file has no other link than its name (a hard link put in a staged file's place
/// has two).
fn single(m: &std::fs::Metadata) -> bool {
    #[cfg(unix)]
    return std::os::unix::fs::MetadataExt::nlink(m) == 1;
    #[cfg(not(unix))]
    return true;
}

/// A number another user cannot predict: the staged files' names end with one, so that no link
/// can be planted at a name before it is created.
pub(crate) fn unpredictable() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    // `RandomState` is keyed from the operating system's randomness.
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u64(SET.fetch_add(1, Ordering::Relaxed));
    let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH);
    h.write_u128(now.map_or(0, |d| d.as_nanos()));
    h.finish()
}

fn forget(tmps: &[PathBuf]) {
    pending().retain(|p| !tmps.contains(p));
    created().retain(|p| !tmps.contains(p));
}

/// Waits for a commit under way, then holds off the next one, and removes the temporary files
/// of the sets not committed: take it in an interrupt handler before ending the process, which
/// then leaves no `.partial` file.
pub fn interrupt_guard() -> std::sync::MutexGuard<'static, ()> {
    let held = RENAMING.lock().unwrap_or_else(|e| e.into_inner());
    let mut pending = pending();
    for p in pending.drain(..) {
        let _ = std::fs::remove_file(p);
    }
    for d in SCRATCH.lock().unwrap_or_else(|e| e.into_inner()).drain(..) {
        let _ = std::fs::remove_dir_all(d);
    }
    ENDING.store(true, Ordering::SeqCst);
    held
}

/// Directories of the process's own (a server's scratch directory) that an interrupt removes
/// with what they hold ([`interrupt_guard`]).
static SCRATCH: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// Has an interrupt remove the directory `dir` and its contents before the process ends.
pub fn remove_on_interrupt(dir: PathBuf) {
    SCRATCH.lock().unwrap_or_else(|e| e.into_inner()).push(dir);
}

/// Exit status of a process ended by an interrupt (128 + SIGINT).
pub const INTERRUPTED: i32 = 130;

impl Staged {
    pub fn new() -> Self {
        Staged::default()
    }

    /// Reserves `final_path`; returns the temporary path to write instead:
    /// `FINAL.PID-R.partial`, R a number nobody can predict, created here exclusively (a name
    /// that exists, a planted link included, is never opened: another is drawn), so that
    /// concurrent runs never share one and [`create`] writes only to this file. Where it cannot
    /// be created (a read-only folder), [`create`] reports why.
    pub fn path(&mut self, final_path: &Path) -> PathBuf {
        let name = || {
            let mut tmp = final_path.as_os_str().to_owned();
            tmp.push(format!(
                ".{}-{}.partial",
                std::process::id(),
                unpredictable()
            ));
            PathBuf::from(tmp)
        };
        let mut guard = pending();
        if ENDING.load(Ordering::SeqCst) {
            drop(guard);
            loop {
                std::thread::park();
            }
        }
        let mut tmp = name();
        for _ in 0..16 {
            match exclusive(&tmp) {
                Ok(_) => {
                    created().push(tmp.clone());
                    break;
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => tmp = name(),
                Err(_) => break,
            }
        }
        guard.push(tmp.clone());
        drop(guard);
        self.files.push((tmp.clone(), final_path.to_path_buf()));
        tmp
    }

    /// Writes bytes to a staged file.
    pub fn write(&mut self, final_path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
        let tmp = self.path(final_path);
        std::io::Write::write_all(&mut create(&tmp).map_err(io(final_path))?, bytes)
            .map_err(io(final_path))
    }

    /// Writes `value` as pretty JSON to a staged file, through a `serde_json::Value` (whose
    /// maps sort their keys: a stable file whatever the field order).
    pub fn write_json<T: serde::Serialize>(
        &mut self,
        final_path: &Path,
        value: &T,
    ) -> Result<(), OutputError> {
        let files = self.manifest(final_path);
        let text = serde_json::to_value(value)
            .map(|mut v| {
                if let Some(o) = v.as_object_mut() {
                    o.insert("files".into(), files.into());
                }
                v
            })
            .and_then(|v| serde_json::to_string_pretty(&v))
            .map_err(|e| other(final_path, e.to_string()))?;
        self.write(final_path, text.as_bytes())
    }

    /// Makes `json` the set's manifest and returns what it must list as `files`: the names of
    /// the set's files (those staged so far, `json` and [`Staged::also_list`]'s). At commit,
    /// the files the JSON being replaced lists and this set does not write are removed, so that
    /// a set never stands beside the rest of another command's set at the same prefix.
    pub fn manifest(&mut self, json: &Path) -> Vec<String> {
        self.manifest = Some(json.to_path_buf());
        let mut names: Vec<String> = self
            .files
            .iter()
            .map(|f| f.1.as_path())
            .chain([json])
            .chain(self.listed.iter().map(PathBuf::as_path))
            .filter_map(|p| Some(p.file_name()?.to_string_lossy().into_owned()))
            .collect();
        names.sort();
        names.dedup();
        names
    }

    /// Lists `path` in the manifest though another set of the run commits it.
    pub fn also_list(&mut self, path: &Path) {
        self.listed.push(path.to_path_buf());
    }

    /// The set is computed from `path` as it was when its fingerprint was `sum`: the commit
    /// fails, leaving everything as it is, if the file has changed since (another run
    /// replaced the set it belongs to).
    pub fn read_from(&mut self, path: &Path, sum: String) {
        self.read.push((path.to_path_buf(), sum));
    }

    /// `path`, if it exists, is removed at commit: the set no longer contains it.
    pub fn remove_stale(&mut self, path: &Path) {
        self.stale.push(path.to_path_buf());
    }

    /// Renames every staged file into place; returns the final paths.
    pub fn commit(mut self) -> Result<Vec<PathBuf>, OutputError> {
        let files = std::mem::take(&mut self.files);
        let Some((_, first)) = files.first() else {
            return Ok(Vec::new());
        };
        let lock = DirLock::acquire(first)?;
        let renaming = RENAMING.lock().unwrap_or_else(|e| e.into_inner());
        let tmps: Vec<PathBuf> = files.iter().map(|f| f.0.clone()).collect();
        let result = self.rename_all(files);
        forget(&tmps);
        // The lock file goes before an interrupt waiting on `renaming` may end the process.
        drop(lock);
        drop(renaming);
        result
    }

    /// The renames of [`Staged::commit`], under its lock.
    fn rename_all(&mut self, files: Vec<(PathBuf, PathBuf)>) -> Result<Vec<PathBuf>, OutputError> {
        // Every file the set was computed from is as it was, and every destination and every
        // stale file to remove is checked, before the first rename: a failure leaves nothing.
        for (path, sum) in &self.read {
            if fingerprint(path).as_ref() != Some(sum) {
                self.files = files.clone();
                return Err(other(
                    path,
                    "changed while this set was computed from it (another run replaced it): \
                     nothing written",
                ));
            }
        }
        // Each staged name still holds the file written to it: never a link renamed into place.
        for (tmp, _) in &files {
            if !std::fs::symlink_metadata(tmp).is_ok_and(|m| m.file_type().is_file() && single(&m))
            {
                self.files = files.clone();
                return Err(other(
                    tmp,
                    "is not the file rattle staged (a link or another file was put in its \
                     place): nothing written",
                ));
            }
        }
        for dst in files.iter().map(|f| &f.1).chain(&self.stale) {
            if dst.is_dir() {
                self.files = files.clone();
                return Err(other(dst, "a directory is in the way"));
            }
        }
        if let Err(e) = self.seal(&files) {
            // Not committed: the staged files are removed with the set.
            self.files = files.clone();
            return Err(e);
        }
        // What the set being replaced listed and this one does not write, read before its JSON
        // is replaced.
        let ours: Vec<&Path> = files
            .iter()
            .map(|f| f.1.as_path())
            .chain(self.listed.iter().map(PathBuf::as_path))
            .collect();
        let replaced: Vec<PathBuf> = self
            .manifest
            .as_deref()
            .map(listed_by)
            .unwrap_or_default()
            .into_iter()
            .filter(|p| !ours.contains(&p.as_path()))
            .collect();
        let mut done = Vec::new();
        for (tmp, dst) in &files {
            if let Err(e) = std::fs::rename(tmp, dst) {
                self.files = files[done.len()..].to_vec();
                return Err(io(dst)(e));
            }
            done.push(dst.clone());
        }
        for p in &self.stale {
            if p.exists() {
                std::fs::remove_file(p).map_err(io(p))?;
            }
        }
        for p in &replaced {
            if p.exists() {
                std::fs::remove_file(p).map_err(io(p))?;
            }
        }
        remove_orphans(&done);
        Ok(done)
    }
}

impl Staged {
    /// Records in the set's JSON (staged, not yet in place) the fingerprint of every file the
    /// set writes, as `file_sums`: a later set removes only files that still match them. The
    /// entry is appended to the JSON object in place (a large set's JSON is not read back).
    fn seal(&self, files: &[(PathBuf, PathBuf)]) -> Result<(), OutputError> {
        use std::io::{Read, Seek, SeekFrom, Write};
        let Some(json) = self.manifest.clone() else {
            return Ok(());
        };
        let Some((tmp, _)) = files.iter().find(|f| f.1 == json) else {
            return Ok(());
        };
        let bad = |e: String| other(&json, e);
        let mut sums = serde_json::Map::new();
        for (t, dst) in files.iter().filter(|f| f.1 != json) {
            let name = dst.file_name().map(|n| n.to_string_lossy().into_owned());
            let (Some(name), Some(sum)) = (name, fingerprint(t)) else {
                return Err(bad(format!("cannot read back {}", t.display())));
            };
            sums.insert(name, sum.into());
        }
        // Files of the run committed by a set of their own before this one, in place by now.
        for p in &self.listed {
            if let (Some(name), Some(sum)) = (p.file_name(), fingerprint(p)) {
                sums.insert(name.to_string_lossy().into_owned(), sum.into());
            }
        }
        let sums = serde_json::to_string(&sums).map_err(|e| bad(e.to_string()))?;
        let mut f = open_own(tmp, false).map_err(|e| bad(e.to_string()))?;
        // The JSON is an object with `files` at least: its last byte closes it.
        let end = f.seek(SeekFrom::End(-1)).map_err(|e| bad(e.to_string()))?;
        let mut last = [0u8];
        f.read_exact(&mut last).map_err(|e| bad(e.to_string()))?;
        if last[0] != b'}' {
            return Err(bad("the set's JSON is not an object".into()));
        }
        f.seek(SeekFrom::Start(end))
            .map_err(|e| bad(e.to_string()))?;
        write!(f, ",\n  \"file_sums\": {sums}\n}}").map_err(|e| bad(e.to_string()))
    }
}

/// Removes the `.partial` files of `finals` that runs killed before their commit left behind
/// (their process is gone): `FINAL.PID-N.partial`. Best effort: a file that cannot be removed
/// stays, and without /proc nothing is removed.
fn remove_orphans(finals: &[PathBuf]) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let mut dirs: Vec<&Path> = finals
        .iter()
        .map(|f| {
            f.parent()
                .filter(|p| !p.as_os_str().is_empty())
                .unwrap_or(Path::new("."))
        })
        .collect();
    dirs.dedup();
    let names: std::collections::HashSet<String> = finals
        .iter()
        .filter_map(|f| f.file_name()?.to_str().map(str::to_string))
        .collect();
    for dir in dirs {
        let Ok(entries) = std::fs::read_dir(dir) else {
            continue;
        };
        for e in entries.flatten() {
            let name = e.file_name();
            let Some(name) = name.to_str() else { continue };
            let Some(stem) = name.strip_suffix(".partial") else {
                continue;
            };
            // FINAL.PID-N: the final name, then the writer's process id.
            let Some((head, n)) = stem.rsplit_once('-') else {
                continue;
            };
            let Some((final_name, pid)) = head.rsplit_once('.') else {
                continue;
            };
            let ours = pid.parse::<u32>().is_ok_and(|p| p == std::process::id());
            let gone = pid
                .parse::<u32>()
                .is_ok_and(|p| !Path::new("/proc").join(p.to_string()).exists());
            if names.contains(final_name) && n.parse::<u64>().is_ok() && !ours && gone {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}

impl Drop for Staged {
    /// An uncommitted set is removed: no half-written output remains after an error.
    fn drop(&mut self) {
        for (tmp, _) in &self.files {
            let _ = std::fs::remove_file(tmp);
        }
        forget(&self.files.iter().map(|f| f.0.clone()).collect::<Vec<_>>());
    }
}

/// The lock of the outputs' directory, held while a set is renamed into place: the
/// operating system's lock on the directory itself (`flock`), released when it is dropped or
/// when its process ends, however it ends. No lock file is left behind, and no lock outlives
/// its run.
struct DirLock(#[allow(dead_code)] std::fs::File);

impl DirLock {
    fn acquire(file: &Path) -> Result<DirLock, OutputError> {
        let dir = file
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let f = std::fs::File::open(dir).map_err(io(dir))?;
        let t = Instant::now();
        let mut told = false;
        loop {
            match f.try_lock() {
                Ok(()) => return Ok(DirLock(f)),
                Err(std::fs::TryLockError::WouldBlock) => {
                    if !told && t.elapsed() > Duration::from_secs(1) {
                        told = true;
                        log::info!(
                            "waiting for another run to finish committing its outputs in {}",
                            dir.display()
                        );
                    }
                    std::thread::sleep(Duration::from_millis(5));
                }
                Err(std::fs::TryLockError::Error(e)) => return Err(io(dir)(e)),
            }
        }
    }
}

/// Reads an input file as text, refusing what is not a regular file (a FIFO nobody writes
/// would block forever; a directory or a device is no config or part either).
pub fn read_input(path: &Path) -> std::io::Result<String> {
    let kind = std::fs::metadata(path)?.file_type();
    if !kind.is_file() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "not a regular file",
        ));
    }
    std::fs::read_to_string(path)
}

/// `PREFIX.ext` for an output prefix.
pub fn with_ext(prefix: &Path, ext: &str) -> PathBuf {
    let mut s = prefix.as_os_str().to_owned();
    s.push(".");
    s.push(ext);
    PathBuf::from(s)
}

/// `PREFIX-suffix` for an output prefix.
pub fn with_suffix(prefix: &Path, suffix: &str) -> PathBuf {
    let mut s = prefix.as_os_str().to_owned();
    s.push("-");
    s.push(suffix);
    PathBuf::from(s)
}

/// The extensions of every file a set writes.
const OUTPUT_EXTS: [&str; 5] = ["png", "svg", "json", "csv", "npy"];

/// Checks, before any computation, that files `PREFIX.*` can be written: the prefix names a
/// file (not a directory), its directory exists and is writable, and none of `PREFIX.ext`
/// for `exts` is a directory.
pub fn check_prefix(prefix: &Path, exts: &[&str]) -> Result<(), OutputError> {
    check_prefix_within(prefix, exts, None)
}

/// [`check_prefix`] for files a set at `prefix` writes as part of the set whose JSON is `own`
/// (a map's boundaries, `PREFIX-boundaries.*` in the set of `PREFIX.json`): that set owning
/// them is no conflict, the run replaces it.
pub fn check_prefix_within(
    prefix: &Path,
    exts: &[&str],
    own: Option<&Path>,
) -> Result<(), OutputError> {
    let s = prefix.as_os_str().to_string_lossy();
    if s.is_empty() || s.ends_with('/') || prefix.is_dir() || prefix.file_name().is_none() {
        return Err(other(
            prefix,
            "the output prefix must name files, e.g. results/fig2 (not a directory)",
        ));
    }
    let dir = prefix
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !dir.is_dir() {
        // Name what is wrong: a file where a directory should be, or a directory missing.
        if let Some(file) = dir.ancestors().find(|a| a.exists()).filter(|a| !a.is_dir()) {
            return Err(other(file, "a file is in the way of the output directory"));
        }
        return Err(other(dir, "the output directory does not exist"));
    }
    // Created exclusively under a name nobody predicts: never written through a link.
    let probe = dir.join(format!(
        ".rattle-probe-{}-{}",
        std::process::id(),
        unpredictable()
    ));
    exclusive(&probe).map_err(io(dir))?;
    let _ = std::fs::remove_file(&probe);
    for ext in exts {
        let p = with_ext(prefix, ext);
        if p.is_dir() {
            return Err(other(&p, "a directory is in the way"));
        }
    }
    // A directory in the way of any other file of the set (`PREFIX-class.npy`), refused now
    // rather than after computing.
    let name = prefix.file_name().and_then(|n| n.to_str()).unwrap_or("");
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries.flatten() {
            let n = e.file_name();
            let Some(n) = n.to_str() else { continue };
            let ours = n.starts_with(&format!("{name}-"))
                && OUTPUT_EXTS.iter().any(|x| n.ends_with(&format!(".{x}")));
            if ours && e.file_type().is_ok_and(|t| t.is_dir()) {
                return Err(other(&e.path(), "a directory is in the way"));
            }
        }
    }
    if let Some((file, json)) =
        owned_by_another_set(prefix).filter(|(_, j)| Some(j.as_path()) != own)
    {
        return Err(other(
            &file,
            format!(
                "it belongs to the set of {} (written by an earlier run), which a set at this \
                 prefix would overwrite; choose another prefix",
                json.display()
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A link or another file put in the place of a staged file after [`Staged::path`] created
    /// it is never written through, and the commit renames nothing.
    #[cfg(unix)]
    #[test]
    fn a_staged_file_swapped_for_a_link_is_not_written_through() {
        let d = std::env::temp_dir().join(format!("rattle-staged-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        let victim = d.join("victim.txt");
        std::fs::write(&victim, "mine\n").unwrap();
        let fin = d.join("out.json");
        let mut st = Staged::new();
        let tmp = st.path(&fin);
        // Created at once, as a regular file, under a name that ends in an unpredictable number.
        assert!(
            std::fs::symlink_metadata(&tmp)
                .unwrap()
                .file_type()
                .is_file()
        );
        assert_ne!(st.path(&d.join("b.json")), tmp);
        std::fs::remove_file(&tmp).unwrap();
        std::os::unix::fs::symlink(&victim, &tmp).unwrap();
        let e = create(&tmp).unwrap_err();
        assert!(e.to_string().contains("symbolic link"), "{e}");
        // A hard link to the victim in its place is refused too.
        std::fs::remove_file(&tmp).unwrap();
        std::fs::hard_link(&victim, &tmp).unwrap();
        assert!(create(&tmp).is_err());
        assert!(st.commit().is_err());
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "mine\n");
        assert!(!fin.exists());
        // A name the process did not stage is never written through a link.
        let planted = d.join("planted");
        std::os::unix::fs::symlink(&victim, &planted).unwrap();
        assert!(create(&planted).is_err());
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "mine\n");
        let _ = std::fs::remove_dir_all(&d);
    }
}
