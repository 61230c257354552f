//! The one rule for every file nudyn writes: a new path or a regular file
//! is replaced whole, by a temporary file beside it that is synced and then
//! renamed over it; anything else (a device such as /dev/null, a FIFO, a
//! socket, a directory) is refused, never renamed over. A symbolic link is
//! followed: the file it points to is replaced, and the link stays.
//!
//! The rename is what makes a failure (a full disk) or a concurrent write
//! leave either the whole new file or what was there before; it is also
//! why the rule is needed: renamed over a device node or a FIFO, it would
//! turn it into a regular file (as root, `-o /dev/null` did).

use std::fs::{File, FileType};
use std::path::{Path, PathBuf};

/// Why a path cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The path is there and is not a regular file.
    #[error("{} is a {kind}, not a regular file: nudyn writes only regular files and new paths", path.display())]
    NotRegular {
        /// The path as given.
        path: PathBuf,
        /// What it is.
        kind: &'static str,
    },
    /// The path, its directory or the temporary file cannot be used.
    #[error("{}: {source}", path.display())]
    Io {
        /// The path concerned.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// What a file that is not a regular file is, in words.
fn kind(file_type: FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if file_type.is_char_device() {
            return "character device";
        }
        if file_type.is_block_device() {
            return "block device";
        }
        if file_type.is_fifo() {
            return "FIFO";
        }
        if file_type.is_socket() {
            return "socket";
        }
    }
    if file_type.is_dir() { "directory" } else { "special file" }
}

/// The file `out` names, if nudyn may replace it: `out` itself when it is
/// new or a regular file, the file a symbolic link points to when that is
/// a regular file.
pub fn replaceable(out: &Path) -> Result<PathBuf, OutputError> {
    let io_error = |source| OutputError::Io { path: out.to_path_buf(), source };
    let metadata = match std::fs::symlink_metadata(out) {
        Err(error) if error.kind() == std::io::ErrorKind::NotFound => return Ok(out.to_path_buf()),
        metadata => metadata.map_err(io_error)?,
    };
    let (target, file_type) = if metadata.file_type().is_symlink() {
        // A link to nothing is refused too: where it would be created is not obvious.
        let target = std::fs::canonicalize(out).map_err(io_error)?;
        let file_type = std::fs::metadata(&target).map_err(io_error)?.file_type();
        (target, file_type)
    } else {
        (out.to_path_buf(), metadata.file_type())
    };
    if !file_type.is_file() {
        return Err(OutputError::NotRegular { path: out.to_path_buf(), kind: kind(file_type) });
    }
    Ok(target)
}

/// Writes `out` by the rule above: `write` fills the temporary file, which
/// is then synced, made readable by all (0644; a temporary file is 0600)
/// and renamed over the file `out` names, checked again just before.
pub fn write_atomically<E: From<OutputError>>(out: &Path, write: impl FnOnce(&File) -> Result<(), E>) -> Result<(), E> {
    let target = replaceable(out)?;
    let directory = match target.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    };
    let directory_error = |source| OutputError::Io { path: directory.to_path_buf(), source };
    std::fs::metadata(directory).map_err(directory_error)?;
    let staged = tempfile::Builder::new()
        .prefix(".nudyn-")
        .suffix(".partial")
        .tempfile_in(directory)
        // tempfile's message names the random file it tried, which means nothing to the user.
        .map_err(|error| directory_error(std::io::Error::from(error.kind())))?;
    write(staged.as_file())?;
    let io_error = |source| OutputError::Io { path: out.to_path_buf(), source };
    staged.as_file().sync_all().map_err(io_error)?;
    #[cfg(unix)]
    std::fs::set_permissions(staged.path(), std::os::unix::fs::PermissionsExt::from_mode(0o644)).map_err(io_error)?;
    // Whatever took the path's place while the file was written is not renamed over either.
    if replaceable(out)? != target {
        return Err(io_error(std::io::Error::other("the path changed while it was written")).into());
    }
    staged.persist(&target).map_err(|error| io_error(error.error))?;
    Ok(())
}

// The cases use Unix files (FIFOs, /dev/null, symbolic links).
#[cfg(all(test, unix))]
mod tests {
    use std::io::Write;
    use std::process::Command;

    use super::*;

    fn write(out: &Path, text: &str) -> Result<(), OutputError> {
        write_atomically(out, |mut file: &File| {
            file.write_all(text.as_bytes()).map_err(|source| OutputError::Io { path: out.into(), source })
        })
    }

    #[test]
    fn new_paths_and_regular_files_are_replaced_whole() {
        let directory = tempfile::tempdir().expect("a temporary directory");
        let out = directory.path().join("out.txt");
        write(&out, "first").expect("a new path");
        write(&out, "second").expect("a regular file");
        assert_eq!(std::fs::read_to_string(&out).expect("written"), "second");
        let names: Vec<_> =
            std::fs::read_dir(directory.path()).expect("listed").map(|e| e.expect("entry").file_name()).collect();
        assert_eq!(names, ["out.txt"], "no temporary file left behind");
    }

    #[test]
    fn a_fifo_or_a_directory_is_refused_and_left_as_it_was() {
        let directory = tempfile::tempdir().expect("a temporary directory");
        let fifo = directory.path().join("pipe");
        assert!(Command::new("mkfifo").arg(&fifo).status().expect("mkfifo runs").success());
        let error = write(&fifo, "x").expect_err("a FIFO");
        assert!(
            error
                .to_string()
                .ends_with("pipe is a FIFO, not a regular file: nudyn writes only regular files and new paths"),
            "{error}"
        );
        assert!(std::os::unix::fs::FileTypeExt::is_fifo(
            &std::fs::symlink_metadata(&fifo).expect("still there").file_type()
        ));
        let error = write(directory.path(), "x").expect_err("a directory");
        assert!(error.to_string().contains("is a directory, not a regular file"), "{error}");
        // Only asked, never written: were the rule broken, writing would replace the device node (as root).
        let error = replaceable(Path::new("/dev/null")).expect_err("a device");
        assert!(error.to_string().contains("/dev/null is a character device"), "{error}");
        assert_eq!(std::fs::read_dir(directory.path()).expect("listed").count(), 1, "no temporary file left behind");
    }

    #[test]
    fn a_symbolic_link_is_written_through() {
        let directory = tempfile::tempdir().expect("a temporary directory");
        let (file, link) = (directory.path().join("file"), directory.path().join("link"));
        std::fs::write(&file, "old").expect("written");
        std::os::unix::fs::symlink(&file, &link).expect("linked");
        write(&link, "new").expect("through the link");
        assert_eq!(std::fs::read_to_string(&file).expect("read"), "new");
        assert!(std::fs::symlink_metadata(&link).expect("the link").file_type().is_symlink(), "the link stays");
        let fifo = directory.path().join("pipe");
        assert!(Command::new("mkfifo").arg(&fifo).status().expect("mkfifo runs").success());
        let to_fifo = directory.path().join("to_pipe");
        std::os::unix::fs::symlink(&fifo, &to_fifo).expect("linked");
        let error = write(&to_fifo, "x").expect_err("a link to a FIFO");
        assert!(error.to_string().contains("to_pipe is a FIFO"), "{error}");
    }
}
