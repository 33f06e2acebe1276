//! Files the tool writes: always under a temporary name beside the target, renamed over it only
//! when the command succeeded, so an existing file is never truncated by a run that fails
//! (missing input, full disk, a closed pipe, Ctrl-C before the end), and reading a file while
//! writing the same file is refused before anything is opened for writing.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use tempfile::TempPath;

/// A file being written: the bytes go to a temporary file in the target's directory;
/// [`OutputFile::commit`] renames it over the target. Dropped without a commit, the temporary
/// file is removed and the target is untouched.
#[derive(Debug)]
pub struct OutputFile {
    writer: BufWriter<File>,
    pending: PendingRename,
}

/// The rename that finishes an [`OutputFile`] whose bytes were written through another owner
/// (for example a raw log handed to the serial link). A target that exists and is not a regular
/// file (`/dev/null`, a FIFO, a terminal) is written directly and never renamed over.
#[derive(Debug)]
pub struct PendingRename {
    temporary: Option<TempPath>,
    target: PathBuf,
}

/// A new temporary file in `target`'s directory, named `.NAME.XXXXXX.partial` and then
/// `extension` (which image writers use to choose their format).
fn temporary_beside(target: &Path, extension: &str) -> anyhow::Result<tempfile::NamedTempFile> {
    let directory = match target.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = target
        .file_name()
        .map(|name| name.to_string_lossy().into_owned())
        .unwrap_or_default();
    tempfile::Builder::new()
        .prefix(&format!(".{name}."))
        .suffix(&format!(".partial{extension}"))
        .tempfile_in(&directory)
        .with_context(|| format!("creating a file in {}", directory.display()))
}

/// Whether `target` exists as something other than a regular file or a directory: written in
/// place, since replacing a device or a pipe by a file would be wrong.
fn is_special_file(target: &Path) -> bool {
    std::fs::metadata(target).is_ok_and(|metadata| !metadata.is_file() && !metadata.is_dir())
}

impl OutputFile {
    /// Starts writing `target`. Fails, touching nothing, if the target is a directory or its
    /// directory does not exist or is not writable.
    pub fn create(target: &Path) -> anyhow::Result<Self> {
        if target.is_dir() {
            bail!("{} is a directory, not a file", target.display());
        }
        if is_special_file(target) {
            let file = std::fs::OpenOptions::new()
                .write(true)
                .open(target)
                .with_context(|| format!("opening {}", target.display()))?;
            return Ok(Self {
                writer: BufWriter::new(file),
                pending: PendingRename {
                    temporary: None,
                    target: target.to_path_buf(),
                },
            });
        }
        let file = temporary_beside(target, "")?;
        let (file, temporary) = file.into_parts();
        Ok(Self {
            writer: BufWriter::new(file),
            pending: PendingRename {
                temporary: Some(temporary),
                target: target.to_path_buf(),
            },
        })
    }

    /// The file that will be replaced.
    pub fn target(&self) -> &Path {
        &self.pending.target
    }

    /// Flushes everything to disk and renames the file over the target.
    pub fn commit(self) -> anyhow::Result<()> {
        let Self { writer, pending } = self;
        let file = writer
            .into_inner()
            .map_err(|error| error.into_error())
            .with_context(|| format!("writing {}", pending.target.display()))?;
        pending.commit_file(file)
    }

    /// Splits the file into its writer and the rename that finishes it, for a writer that
    /// another owner keeps until the end.
    pub fn into_parts(self) -> (BufWriter<File>, PendingRename) {
        (self.writer, self.pending)
    }
}

impl Write for OutputFile {
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        self.writer.write(bytes)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.writer.flush()
    }
}

impl PendingRename {
    /// A temporary file beside `target` with the same extension, for writers that want a path
    /// and choose their format by its extension (image encoders); write it, then commit.
    pub fn beside(target: &Path) -> anyhow::Result<Self> {
        if target.is_dir() {
            bail!("{} is a directory, not a file", target.display());
        }
        if is_special_file(target) {
            return Ok(Self {
                temporary: None,
                target: target.to_path_buf(),
            });
        }
        let extension = target
            .extension()
            .map(|extension| format!(".{}", extension.to_string_lossy()))
            .unwrap_or_default();
        let temporary = temporary_beside(target, &extension)?.into_temp_path();
        Ok(Self {
            temporary: Some(temporary),
            target: target.to_path_buf(),
        })
    }

    /// Where the bytes go until the commit.
    pub fn path(&self) -> &Path {
        match &self.temporary {
            Some(temporary) => temporary,
            None => &self.target,
        }
    }

    /// The file that will be replaced.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Syncs `file` (the writer given out by [`OutputFile::into_parts`], already flushed) and
    /// renames the temporary file over the target.
    pub fn commit_file(self, file: File) -> anyhow::Result<()> {
        if self.temporary.is_some() {
            file.sync_all()
                .with_context(|| format!("writing {}", self.target.display()))?;
        }
        drop(file);
        self.commit()
    }

    /// Renames the temporary file over the target (its writer must be flushed and closed).
    pub fn commit(self) -> anyhow::Result<()> {
        let target = self.target;
        match self.temporary {
            Some(temporary) => temporary
                .persist(&target)
                .map_err(|error| error.error)
                .with_context(|| format!("renaming the finished file to {}", target.display())),
            None => Ok(()),
        }
    }

    /// Keeps the temporary file under its own name (a recording that could not be finished
    /// keeps what it has) and returns that name.
    pub fn keep(self) -> anyhow::Result<PathBuf> {
        match self.temporary {
            Some(temporary) => temporary
                .keep()
                .map_err(|error| error.error)
                .context("keeping the partial file"),
            None => Ok(self.target),
        }
    }
}

/// Refuses to write `output` while reading `input` when both name the same file (also through
/// links or different spellings); `-` (stdin) never clashes.
pub fn refuse_same_file(input: &Path, output: &Path) -> anyhow::Result<()> {
    if input.as_os_str() == "-" {
        return Ok(());
    }
    if same_file(input, output) {
        bail!(
            "the output {} is the input {}: choose another output file (the input would be lost)",
            output.display(),
            input.display()
        );
    }
    Ok(())
}

#[cfg(unix)]
fn same_file(first: &Path, second: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(first), std::fs::metadata(second)) {
        (Ok(first), Ok(second)) => first.dev() == second.dev() && first.ino() == second.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(first: &Path, second: &Path) -> bool {
    match (first.canonicalize(), second.canonicalize()) {
        (Ok(first), Ok(second)) => first == second,
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn target_is_replaced_only_on_commit() {
        let directory = tempfile::tempdir().unwrap();
        let target = directory.path().join("out.csv");
        std::fs::write(&target, "precious").unwrap();
        let mut abandoned = OutputFile::create(&target).unwrap();
        abandoned.write_all(b"half").unwrap();
        drop(abandoned);
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "precious");
        assert_eq!(std::fs::read_dir(directory.path()).unwrap().count(), 1);
        let mut finished = OutputFile::create(&target).unwrap();
        finished.write_all(b"new").unwrap();
        finished.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "new");
        assert_eq!(std::fs::read_dir(directory.path()).unwrap().count(), 1);
    }

    #[test]
    fn same_file_is_recognised_through_another_spelling() {
        let directory = tempfile::tempdir().unwrap();
        let file = directory.path().join("a.csv");
        std::fs::write(&file, "x").unwrap();
        let other_spelling = directory.path().join(".").join("a.csv");
        assert!(refuse_same_file(&file, &other_spelling).is_err());
        assert!(refuse_same_file(&file, &directory.path().join("b.csv")).is_ok());
        assert!(refuse_same_file(Path::new("-"), &file).is_ok());
    }
}
