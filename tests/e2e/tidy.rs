//! Tidy: rules of the code base that no compiler checks, in the spirit of rust-analyzer's
//! `tidy` — the crate dependency rules of ARCHITECTURE.md ("Invariants", read from
//! `cargo metadata`), every Rust file opening with a `//!` line, no comment that names a work
//! item (the word "issue" and a number), and every repository path a comment or document names
//! existing.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("repository root")
}

/// The repository's tracked files (and new ones not ignored), relative to the root.
fn files() -> Vec<PathBuf> {
    let o = Command::new("git")
        .args(["ls-files", "--cached", "--others", "--exclude-standard"])
        .current_dir(root())
        .output()
        .expect("git runs");
    assert!(o.status.success(), "git ls-files failed");
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(PathBuf::from)
        .filter(|p| root().join(p).is_file())
        .collect()
}

/// Each workspace crate and the names of the crates it declares as dependencies.
fn dependencies() -> BTreeMap<String, Vec<String>> {
    let o = Command::new(env!("CARGO"))
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .current_dir(root())
        .output()
        .expect("cargo metadata runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    v["packages"]
        .as_array()
        .expect("packages")
        .iter()
        .map(|p| {
            let deps = p["dependencies"]
                .as_array()
                .expect("dependencies")
                .iter()
                .filter(|d| d["kind"].is_null()) // normal dependencies, not dev or build
                .map(|d| d["name"].as_str().expect("name").to_string())
                .collect();
            (p["name"].as_str().expect("name").to_string(), deps)
        })
        .collect()
}

#[test]
fn crate_dependencies_follow_the_architecture() {
    let deps = dependencies();
    for name in [
        "sc_core",
        "sc_raster",
        "sc_view_plan",
        "sc_view_gpu",
        "sc_view_window",
    ] {
        assert!(deps.contains_key(name), "no crate {name}");
    }
    let uses = |krate: &str, dep: &str| deps[krate].iter().any(|d| d == dep);
    let mut broken = Vec::new();
    let mut rule = |ok: bool, what: String| {
        if !ok {
            broken.push(what);
        }
    };
    for (krate, d) in &deps {
        for dep in d {
            rule(
                !(dep == "gdal" || dep == "gdal-sys") || krate == "sc_raster",
                format!("{krate} links GDAL (only sc_raster may)"),
            );
            rule(
                dep != "anyhow" || krate == "sphereclip",
                format!("{krate} uses anyhow (only sphereclip may)"),
            );
            rule(
                dep != "winit" || krate == "sc_view_window" || krate == "sphereclip",
                format!("{krate} links winit"),
            );
        }
    }
    for dep in ["sc_store", "sc_raster", "wgpu", "gdal"] {
        rule(!uses("sc_core", dep), format!("sc_core depends on {dep}"));
    }
    for dep in [
        "wgpu",
        "winit",
        "egui",
        "egui-wgpu",
        "egui-winit",
        "sc_view_gpu",
    ] {
        rule(
            !uses("sc_view_plan", dep),
            format!("sc_view_plan depends on {dep}"),
        );
    }
    for dep in ["winit", "egui", "egui-winit", "egui-wgpu", "sc_view_window"] {
        rule(
            !uses("sc_view_gpu", dep),
            format!("sc_view_gpu depends on {dep}"),
        );
    }
    assert!(broken.is_empty(), "{}", broken.join("\n"));
}

#[test]
fn every_rust_file_opens_with_a_doc_line_and_names_no_work_item() {
    let mut broken = Vec::new();
    for f in files()
        .iter()
        .filter(|f| f.extension().is_some_and(|e| e == "rs"))
    {
        let text = std::fs::read_to_string(root().join(f)).expect("read");
        if !text.starts_with("//!") {
            broken.push(format!("{}: does not open with a `//!` line", f.display()));
        }
        for (n, line) in text.lines().enumerate() {
            let Some(k) = line.find("//") else { continue };
            let comment = line[k..].to_ascii_lowercase();
            let words: Vec<&str> = comment
                .split(|c: char| !c.is_ascii_alphanumeric() && c != '#')
                .filter(|w| !w.is_empty())
                .collect();
            for w in words.windows(2) {
                let number = w[1].trim_start_matches('#');
                if w[0] == "issue"
                    && !number.is_empty()
                    && number.chars().all(|c| c.is_ascii_digit())
                {
                    broken.push(format!("{}:{}: names a work item", f.display(), n + 1));
                }
            }
        }
    }
    assert!(broken.is_empty(), "{}", broken.join("\n"));
}

#[test]
fn every_repository_path_named_in_comments_and_documents_exists() {
    let tops = [
        "tools/", "viewer/", "shaders/", "bench/", "scripts/", "docs/", "samples/", "tests/",
    ];
    let exts = [
        ".rs", ".wgsl", ".toml", ".sh", ".md", ".json", ".txt", ".py", ".png",
    ];
    let mut broken = Vec::new();
    for f in files().iter().filter(|f| {
        f.extension()
            .is_some_and(|e| ["rs", "md", "wgsl", "sh", "toml"].contains(&e.to_str().unwrap_or("")))
    }) {
        let text = std::fs::read_to_string(root().join(f)).expect("read");
        for (n, line) in text.lines().enumerate() {
            for top in tops {
                let mut rest = line;
                while let Some(k) = rest.find(top) {
                    let before = rest[..k].chars().last();
                    let path: String = rest[k..]
                        .chars()
                        .take_while(|c| c.is_ascii_alphanumeric() || "_./-".contains(*c))
                        .collect();
                    rest = &rest[k + top.len()..];
                    // a path of its own (not the tail of another), naming a file by extension
                    if before.is_some_and(|c| c.is_ascii_alphanumeric() || "_/.-".contains(c)) {
                        continue;
                    }
                    let path = path.trim_end_matches('.');
                    if exts.iter().any(|e| path.ends_with(e)) && !root().join(path).exists() {
                        broken.push(format!("{}:{}: {path} does not exist", f.display(), n + 1));
                    }
                }
            }
        }
    }
    assert!(broken.is_empty(), "{}", broken.join("\n"));
}
