//! Opening the files a store (or a plan) names as untrusted: only regular files, never through a
//! symbolic link at the last component, never blocking on a FIFO or a device, reads bounded in
//! size. A damaged or hostile store then gives an error instead of a hang, a spin on `/dev/zero`
//! or a write outside the store.

use std::fs::{File, OpenOptions};
use std::io::{self, Read};
#[cfg(unix)]
use std::os::unix::fs::OpenOptionsExt;
use std::path::Path;

/// Flags of every open here: the last component is not followed if it is a symlink (`ELOOP`),
/// and opening a FIFO or a device does not wait for a peer.
#[cfg(unix)]
const FLAGS: i32 = libc::O_NOFOLLOW | libc::O_NONBLOCK | libc::O_CLOEXEC;

/// Where there is no safe open (a browser has no folders), files are not opened at all.
#[cfg(not(unix))]
fn no_files() -> io::Error {
    io::Error::new(
        io::ErrorKind::Unsupported,
        "store folders are read only on Unix here",
    )
}

/// Turns the errors of a refused open into ones that say why.
#[cfg(unix)]
fn explain(e: io::Error) -> io::Error {
    if e.raw_os_error() == Some(libc::ELOOP) {
        return io::Error::new(
            io::ErrorKind::InvalidData,
            "a symbolic link, which is never followed",
        );
    }
    if e.raw_os_error() == Some(libc::ENXIO) {
        return io::Error::new(io::ErrorKind::InvalidData, "not a regular file");
    }
    e
}

/// Refuses an opened file that is not a regular file (a FIFO, a device, a socket, a folder).
fn regular(f: File) -> io::Result<File> {
    let m = f.metadata()?;
    if m.is_file() {
        Ok(f)
    } else {
        Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("not a regular file but {}", kind_of(&m.file_type())),
        ))
    }
}

/// A word for a file type, for messages.
pub fn kind_of(t: &std::fs::FileType) -> &'static str {
    if t.is_symlink() {
        return "a symbolic link";
    }
    if t.is_dir() {
        return "a folder";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_char_device() || t.is_block_device() {
            return "a device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "a file"
}

/// Opens `path` for reading: a regular file, not a symlink, without blocking.
pub fn open_regular(path: &Path) -> io::Result<File> {
    #[cfg(unix)]
    {
        let f = OpenOptions::new()
            .read(true)
            .custom_flags(FLAGS)
            .open(path)
            .map_err(explain)?;
        regular(f)
    }
    #[cfg(not(unix))]
    {
        let _ = (path, OpenOptions::new(), regular);
        Err(no_files())
    }
}

/// Reads all of the regular file `path` (see [`open_regular`]), refusing one larger than `limit`
/// bytes before reading it.
pub fn read_regular(path: &Path, limit: u64) -> io::Result<Vec<u8>> {
    let f = open_regular(path)?;
    let len = f.metadata()?.len();
    if len > limit {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("{len} bytes, more than the {limit} a file of this kind may have"),
        ));
    }
    let mut out = Vec::with_capacity(len as usize);
    // a file growing while it is read stops at the limit too
    f.take(limit + 1).read_to_end(&mut out)?;
    if out.len() as u64 > limit {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("grew past {limit} bytes while read"),
        ));
    }
    Ok(out)
}

/// Reads `path` as text like [`read_regular`].
pub fn read_regular_string(path: &Path, limit: u64) -> io::Result<String> {
    String::from_utf8(read_regular(path, limit)?)
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidData, "not UTF-8 text"))
}

/// Opens (creating it if missing) a lock file for writing: a regular file, never a symlink's
/// target, never a FIFO (which would block).
pub fn open_lock(path: &Path) -> io::Result<File> {
    #[cfg(unix)]
    {
        let f = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .custom_flags(FLAGS)
            .mode(0o644)
            .open(path)
            .map_err(explain)?;
        regular(f)
    }
    #[cfg(not(unix))]
    {
        let _ = path;
        Err(no_files())
    }
}

/// `Ok` when every folder between `root` and `path` (both excluded) is a real folder, not a
/// symlink (a missing one is fine: it is made later, or the file is missing). With the no-follow
/// open of the last component this keeps every open of a store file inside the store.
pub fn check_inside(root: &Path, path: &Path) -> io::Result<()> {
    let Ok(rel) = path.strip_prefix(root) else {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            "outside the store",
        ));
    };
    let mut at = root.to_path_buf();
    let parts: Vec<_> = rel.components().collect();
    for c in parts.iter().take(parts.len().saturating_sub(1)) {
        if !matches!(c, std::path::Component::Normal(_)) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                "a path that leaves the store",
            ));
        }
        at.push(c);
        match std::fs::symlink_metadata(&at) {
            Ok(m) if m.file_type().is_symlink() => {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidData,
                    format!(
                        "a folder on the way is a symbolic link, which is never followed ({})",
                        at.display()
                    ),
                ));
            }
            Ok(m) if !m.is_dir() => {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidData,
                    format!("{} is not a folder", at.display()),
                ));
            }
            Ok(_) => {}
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(()),
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// The first entry below `root` that is neither a regular file nor a folder (a symlink, FIFO,
/// device or socket), with what it is; the store's lock is left to the writer's own check.
/// Folders are read, nothing is followed or opened.
pub fn first_special_entry(root: &Path) -> Option<(std::path::PathBuf, &'static str)> {
    let mut dirs = vec![root.to_path_buf()];
    while let Some(dir) = dirs.pop() {
        let Ok(rd) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in rd.flatten() {
            let Ok(t) = e.file_type() else { continue };
            if t.is_dir() {
                dirs.push(e.path());
            } else if !(t.is_file() || (dir == root && e.file_name() == ".lock")) {
                return Some((e.path(), kind_of(&t)));
            }
        }
    }
    None
}

/// `Ok` when `path` is missing or a regular file that is not a symlink; the error says what it is
/// instead. For files another library opens (it would follow links and wait on FIFOs).
pub fn check_regular_or_missing(path: &Path) -> io::Result<()> {
    match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(e),
        Ok(m) if m.file_type().is_file() => Ok(()),
        Ok(m) => Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("not a regular file but {}", kind_of(&m.file_type())),
        )),
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    #[test]
    fn links_fifos_devices_and_folders_are_refused_without_blocking() {
        let d = tempfile::tempdir().expect("tmp");
        let file = d.path().join("f");
        std::fs::write(&file, b"abc").expect("write");
        assert_eq!(read_regular(&file, 3).expect("read"), b"abc");
        assert!(read_regular(&file, 2).is_err(), "over the limit");

        let link = d.path().join("l");
        std::os::unix::fs::symlink(&file, &link).expect("symlink");
        let e = read_regular(&link, 10).expect_err("a symlink");
        assert!(e.to_string().contains("symbolic link"), "{e}");

        let dangling = d.path().join("dangling");
        let target = d.path().join("made-by-the-link");
        std::os::unix::fs::symlink(&target, &dangling).expect("symlink");
        assert!(open_lock(&dangling).is_err());
        assert!(!target.exists(), "the link's target was created");

        let fifo = d.path().join("fifo");
        let ok = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .expect("mkfifo runs");
        assert!(ok.success());
        let e = read_regular(&fifo, 10).expect_err("a FIFO");
        assert!(e.to_string().contains("not a regular file"), "{e}");
        assert!(open_lock(&fifo).is_err());
        assert!(check_regular_or_missing(&fifo).is_err());

        assert!(read_regular(Path::new("/dev/zero"), 10).is_err());
        assert!(read_regular(d.path(), 10).is_err());
        assert!(check_regular_or_missing(&d.path().join("missing")).is_ok());
        assert!(check_regular_or_missing(&link).is_err());
    }
}
