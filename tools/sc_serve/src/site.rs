//! The web viewer's files, built into the binary (`build.rs`): the page, its script, the
//! wasm-bindgen glue and the viewer compiled to wasm32. `serve` answers them beside the store;
//! `sphereclip web --out SITE` writes them for a static host.

use std::borrow::Cow;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

include!(concat!(env!("OUT_DIR"), "/web_files.rs"));

/// The page's line naming the store it opens; [`files`] sets its value.
const STORE_META: &str = r#"<meta name="sphereclip-store" content="planet.zarr">"#;

/// How to build the viewer into the binary when it is not.
pub const NOT_BUILT: &str = "this sphereclip was built without the web viewer: run `bash scripts/web.sh release` (or `make build`), then build sphereclip again";

/// Whether the web viewer is built in.
pub fn has_viewer() -> bool {
    WEB_FILES.iter().any(|(n, _)| *n == "index.html")
}

/// The content type of a viewer file.
pub fn content_type(name: &str) -> &'static str {
    match name.rsplit_once('.').map_or("", |(_, e)| e) {
        "html" => "text/html; charset=utf-8",
        "js" => "text/javascript; charset=utf-8",
        "wasm" => "application/wasm",
        "css" => "text/css; charset=utf-8",
        "png" => "image/png",
        _ => "application/octet-stream",
    }
}

fn escape_attr(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('"', "&quot;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// A viewer file's bytes, the page's with its store set to `store`.
fn for_store(name: &str, bytes: &'static [u8], store: &str) -> Cow<'static, [u8]> {
    if name != "index.html" {
        return Cow::Borrowed(bytes);
    }
    let page = String::from_utf8_lossy(bytes).replace(
        STORE_META,
        &format!(
            r#"<meta name="sphereclip-store" content="{}">"#,
            escape_attr(store)
        ),
    );
    Cow::Owned(page.into_bytes())
}

/// The viewer's files with the page opening `store` (a URL, or a path relative to the page).
pub fn files(store: &str) -> Vec<(&'static str, Cow<'static, [u8]>)> {
    WEB_FILES
        .iter()
        .map(|&(name, bytes)| (name, for_store(name, bytes, store)))
        .collect()
}

/// A viewer file by name (the page opening `store`), if there is one.
pub fn file(name: &str, store: &str) -> Option<Cow<'static, [u8]>> {
    WEB_FILES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|&(name, bytes)| for_store(name, bytes, store))
}

/// Writes the viewer's files into the folder `out` (made if missing; its parent must exist),
/// the page opening `store`; returns the files written. A file there already is replaced only
/// when it is a regular file (never through a symlink); each is written whole to a temporary
/// file first and renamed into place.
pub fn write_site(out: &Path, store: &str) -> io::Result<Vec<PathBuf>> {
    if !has_viewer() {
        return Err(io::Error::new(io::ErrorKind::Unsupported, NOT_BUILT));
    }
    match std::fs::symlink_metadata(out) {
        Ok(m) if m.is_dir() => {}
        Ok(m) => {
            return Err(io::Error::new(
                io::ErrorKind::AlreadyExists,
                format!(
                    "{} is a {}, not a folder",
                    out.display(),
                    sc_store::files::kind_of(&m.file_type())
                ),
            ));
        }
        Err(e) if e.kind() == io::ErrorKind::NotFound => std::fs::create_dir(out)
            .map_err(|e| io::Error::new(e.kind(), format!("cannot make {}: {e}", out.display())))?,
        Err(e) => return Err(e),
    }
    let mut written = Vec::new();
    for (name, bytes) in files(store) {
        let path = out.join(name);
        sc_store::files::check_regular_or_missing(&path)
            .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", path.display())))?;
        let tmp = out.join(format!(".{name}.tmp"));
        let mut f = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
            .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", tmp.display())))?;
        let done = f
            .write_all(&bytes)
            .and_then(|()| f.sync_all())
            .and_then(|()| std::fs::rename(&tmp, &path));
        if let Err(e) = done {
            let _ = std::fs::remove_file(&tmp);
            return Err(io::Error::new(e.kind(), format!("{}: {e}", path.display())));
        }
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_page_opens_the_store_it_is_given_and_escapes_it() {
        assert!(has_viewer(), "{NOT_BUILT}");
        let page = file("index.html", r#"a"b<c>.zarr"#).expect("index.html");
        let page = String::from_utf8_lossy(&page);
        assert!(
            page.contains(r#"<meta name="sphereclip-store" content="a&quot;b&lt;c&gt;.zarr">"#),
            "{page}"
        );
        assert!(!page.contains(STORE_META));
        assert_eq!(content_type("x.wasm"), "application/wasm");
        assert_eq!(content_type("main.js"), "text/javascript; charset=utf-8");
    }
}
