//! Tidy: rules of the code base that no compiler checks, in the spirit of rust-analyzer's
//! `tidy` — each crate's dependencies exactly as ARCHITECTURE.md's table lists them (from
//! `cargo metadata`), every Rust name ARCHITECTURE.md writes defined in the code, no module
//! importing another that imports it back, every workspace crate with its own opt-level in the
//! profiles, every Rust file opening with a `//!` line, no comment that names a work item (the
//! word "issue" and a number), and every repository path a comment or document names existing.

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

/// ARCHITECTURE.md's table of crates: each crate's name (the first code span of its row) and the
/// names its "may depend on" column (the last cell) lists.
fn architecture_table() -> BTreeMap<String, Vec<String>> {
    let text = std::fs::read_to_string(root().join("ARCHITECTURE.md")).expect("ARCHITECTURE.md");
    let spans = |cell: &str| -> Vec<String> {
        cell.split('`')
            .skip(1)
            .step_by(2)
            .map(str::to_string)
            .collect()
    };
    let mut out = BTreeMap::new();
    for line in text.lines() {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        // | crate | what it is | may depend on |
        if cells.len() != 5 || !cells[1].starts_with('`') {
            continue;
        }
        let name = spans(cells[1]).into_iter().next().expect("a crate name");
        out.insert(name, spans(cells[3]));
    }
    out
}

#[test]
fn crate_dependencies_are_exactly_the_architecture_table() {
    let deps = dependencies();
    let table = architecture_table();
    let mut broken = Vec::new();
    for (krate, actual) in &deps {
        let Some(allowed) = table.get(krate) else {
            broken.push(format!(
                "{krate} is not in ARCHITECTURE.md's table of crates"
            ));
            continue;
        };
        for d in actual {
            if !allowed.contains(d) {
                broken.push(format!(
                    "{krate} depends on {d}, which its row does not list"
                ));
            }
        }
        for d in allowed {
            if !actual.contains(d) {
                broken.push(format!(
                    "{krate}'s row lists {d}, which it does not depend on"
                ));
            }
        }
    }
    for krate in table.keys() {
        if !deps.contains_key(krate) {
            broken.push(format!(
                "ARCHITECTURE.md lists {krate}, which is not a crate"
            ));
        }
    }
    // the rules the table exists for
    for (krate, d) in &deps {
        for dep in d {
            if (dep == "gdal" || dep == "gdal-sys") && krate != "sc_raster" {
                broken.push(format!("{krate} links GDAL (only sc_raster may)"));
            }
            if dep == "anyhow" && krate != "sphereclip" {
                broken.push(format!("{krate} uses anyhow (only sphereclip may)"));
            }
            if dep.starts_with("winit") && krate != "sc_view_window" {
                broken.push(format!("{krate} links winit (only sc_view_window may)"));
            }
            if dep == "wgpu" && (krate == "sc_view_plan" || krate == "sc_core") {
                broken.push(format!("{krate} links wgpu"));
            }
        }
    }
    assert!(broken.is_empty(), "{}", broken.join("\n"));
}

/// Every item name defined in the workspace's Rust code: functions, types, traits, constants,
/// modules (files and folders too), enum variants and fields.
fn defined_names() -> std::collections::BTreeSet<String> {
    let mut out = std::collections::BTreeSet::new();
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect()
    };
    for f in files() {
        let top = f
            .components()
            .next()
            .map(|c| c.as_os_str().to_string_lossy().into_owned());
        if !matches!(top.as_deref(), Some("tools" | "viewer" | "bench" | "tests")) {
            continue;
        }
        for c in f.components() {
            let c = c.as_os_str().to_string_lossy();
            out.insert(c.trim_end_matches(".rs").to_string());
        }
        if f.extension().is_none_or(|e| e != "rs") {
            continue;
        }
        let text = std::fs::read_to_string(root().join(&f)).unwrap_or_default();
        for line in text.lines() {
            let words: Vec<&str> = line.split_whitespace().collect();
            for w in words.windows(2) {
                if matches!(
                    w[0],
                    "fn" | "struct" | "enum" | "trait" | "type" | "const" | "static" | "mod"
                ) {
                    out.insert(ident(w[1]));
                }
            }
            // a variant or a field: `    Name,` `    Name(…)` `    Name {` `    pub name: T`
            let t = line
                .trim_start()
                .trim_start_matches("pub ")
                .trim_start_matches("pub(crate) ");
            let name = ident(t);
            let rest = &t[name.len()..];
            if !name.is_empty()
                && (rest.starts_with(',')
                    || rest.starts_with('(')
                    || rest.starts_with(" {")
                    || rest.starts_with(':'))
            {
                out.insert(name);
            }
        }
    }
    out
}

/// The build-speed rule of Cargo.toml's profiles: dependencies take their opt-level from the
/// profile itself, each workspace crate its own from a named override, and no `package."*"`
/// override sets one (it would also optimise the crates that only run while building — proc
/// macros, build scripts — which Cargo's build-override otherwise builds quickly at opt-level 0).
/// Such an override may set what costs no build time there, as the checked profile's leaves out
/// the dependencies' debug info.
#[test]
fn every_workspace_crate_sets_its_own_opt_level_and_no_wildcard_sets_one() {
    let text = std::fs::read_to_string(root().join("Cargo.toml")).expect("Cargo.toml");
    let manifest: toml::Table = toml::from_str(&text).expect("Cargo.toml parses");
    let profiles = manifest["profile"].as_table().expect("[profile]");
    let mut broken = Vec::new();
    for (name, profile) in profiles {
        let packages = profile.get("package").and_then(toml::Value::as_table);
        if packages
            .and_then(|p| p.get("*"))
            .is_some_and(|all| all.get("opt-level").is_some())
        {
            broken.push(format!(
                "profile.{name} has a package.\"*\" opt-level (set the dependencies' opt-level on the profile)"
            ));
        }
    }
    let dev = profiles["dev"]
        .get("package")
        .and_then(toml::Value::as_table)
        .cloned()
        .unwrap_or_default();
    for krate in dependencies().keys() {
        if dev.get(krate).and_then(|p| p.get("opt-level")).is_none() {
            broken.push(format!(
                "{krate} has no [profile.dev.package.{krate}] opt-level (it would be built like a dependency)"
            ));
        }
    }
    assert!(broken.is_empty(), "{}", broken.join("\n"));
}

#[test]
fn every_rust_name_in_the_architecture_exists() {
    let text = std::fs::read_to_string(root().join("ARCHITECTURE.md")).expect("ARCHITECTURE.md");
    let names = defined_names();
    let is_ident = |s: &str| {
        !s.is_empty()
            && s.chars().all(|c| c.is_alphanumeric() || c == '_')
            && !s.starts_with(|c: char| c.is_ascii_digit())
    };
    let mut missing = Vec::new();
    for span in text.split('`').skip(1).step_by(2) {
        let span = span.trim_end_matches("()");
        let segments: Vec<&str> = span.split("::").collect();
        let camel = |s: &str| {
            s.starts_with(|c: char| c.is_ascii_uppercase())
                && s.chars().any(|c| c.is_ascii_lowercase())
                && !s.contains('_')
        };
        // a path (`a::b`), or a CamelCase name (a type)
        let rusty = (segments.len() > 1 && segments.iter().all(|s| is_ident(s)))
            || (segments.len() == 1 && is_ident(span) && camel(span));
        if rusty {
            for s in segments {
                if !names.contains(s) && !matches!(s, "crate" | "self" | "super") {
                    missing.push(format!("{span} ({s})"));
                }
            }
        }
    }
    missing.sort();
    missing.dedup();
    assert!(
        missing.is_empty(),
        "ARCHITECTURE.md names what the code does not define: {}",
        missing.join(", ")
    );
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
        ".rs", ".wgsl", ".wesl", ".toml", ".sh", ".md", ".json", ".txt", ".py", ".png",
    ];
    let mut broken = Vec::new();
    for f in files().iter().filter(|f| {
        f.extension().is_some_and(|e| {
            ["rs", "md", "wgsl", "wesl", "sh", "toml"].contains(&e.to_str().unwrap_or(""))
        })
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

/// The modules of the crate in `src` (a folder of the repository) and, for each, the crate's
/// other top-level modules its code names (`crate::m`, `use crate::{m, …}`, an item the crate
/// root re-exports from `m`); `super::m` in a submodule and its unit tests (from `#[cfg(test)]`
/// on) left out.
fn module_imports(src: &Path) -> BTreeMap<String, std::collections::BTreeSet<String>> {
    let root_file = ["lib.rs", "main.rs"]
        .iter()
        .map(|f| src.join(f))
        .find(|p| p.is_file());
    let mut modules = std::collections::BTreeSet::new();
    for e in std::fs::read_dir(src).expect("read src").flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if let Some(m) = name.strip_suffix(".rs") {
            if m != "lib" && m != "main" {
                modules.insert(m.to_string());
            }
        } else if e.path().is_dir() && e.path().join("mod.rs").is_file() {
            modules.insert(name);
        }
    }
    // items the root re-exports: `pub use m::{A, B};`, `pub use m::A;`
    let mut reexported: BTreeMap<String, String> = BTreeMap::new();
    if let Some(r) = &root_file {
        let text = std::fs::read_to_string(r).expect("read the crate root");
        for stmt in text.split(';') {
            let Some(path) = stmt.trim().strip_prefix("pub use ") else {
                continue;
            };
            let path = path
                .trim_start_matches("crate::")
                .trim_start_matches("self::");
            let Some((m, items)) = path.split_once("::") else {
                continue;
            };
            if !modules.contains(m) {
                continue;
            }
            for item in items.trim_matches(['{', '}', ' ', '\n']).split(',') {
                let item = item.trim().rsplit("::").next().unwrap_or_default();
                let item = item.split(" as ").last().unwrap_or_default().trim();
                if !item.is_empty() {
                    reexported.insert(item.to_string(), m.to_string());
                }
            }
        }
    }
    let mut out = BTreeMap::new();
    let mut walk = vec![src.to_path_buf()];
    while let Some(dir) = walk.pop() {
        for e in std::fs::read_dir(&dir).expect("read_dir").flatten() {
            let p = e.path();
            if p.is_dir() {
                walk.push(p);
                continue;
            }
            if p.extension().is_none_or(|x| x != "rs") {
                continue;
            }
            let rel = p.strip_prefix(src).expect("inside");
            let first = rel.components().next().expect("a component");
            let module = first
                .as_os_str()
                .to_string_lossy()
                .trim_end_matches(".rs")
                .to_string();
            if !modules.contains(&module) {
                continue; // the crate root, a binary
            }
            let code = code_of(&p);
            let uses: &mut std::collections::BTreeSet<String> =
                out.entry(module.clone()).or_default();
            let mut names = Vec::new();
            for (at, _) in code.match_indices("crate::") {
                let rest = &code[at + "crate::".len()..];
                if let Some(group) = rest.strip_prefix('{') {
                    // the group's top-level items
                    let mut depth = 0;
                    let mut item = String::new();
                    for c in group.chars() {
                        match c {
                            '{' => depth += 1,
                            '}' if depth == 0 => break,
                            '}' => depth -= 1,
                            ',' if depth == 0 => {
                                names.push(std::mem::take(&mut item));
                                continue;
                            }
                            _ => {}
                        }
                        if depth == 0 {
                            item.push(c);
                        }
                    }
                    names.push(item);
                } else {
                    names.push(rest.to_string());
                }
            }
            for n in names {
                let ident: String = n
                    .trim()
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                let target = if modules.contains(&ident) {
                    Some(ident)
                } else {
                    reexported.get(&ident).cloned()
                };
                if let Some(t) = target
                    && t != module
                {
                    uses.insert(t);
                }
            }
        }
    }
    out
}

/// The groups of modules that import each other in a circle (strongly connected, more than one).
fn circles(g: &BTreeMap<String, std::collections::BTreeSet<String>>) -> Vec<Vec<String>> {
    // reachability by search from each module: small graphs
    let reach = |from: &String| {
        let mut seen = std::collections::BTreeSet::new();
        let mut todo = vec![from.clone()];
        while let Some(m) = todo.pop() {
            for n in g.get(&m).into_iter().flatten() {
                if seen.insert(n.clone()) {
                    todo.push(n.clone());
                }
            }
        }
        seen
    };
    let reaches: BTreeMap<&String, _> = g.keys().map(|m| (m, reach(m))).collect();
    let mut done = std::collections::BTreeSet::new();
    let mut out = Vec::new();
    for m in g.keys() {
        if done.contains(m) || !reaches[m].contains(m) {
            continue;
        }
        let group: Vec<String> = g
            .keys()
            .filter(|n| reaches[m].contains(*n) && reaches[*n].contains(m))
            .cloned()
            .collect();
        done.extend(group.iter().cloned());
        out.push(group);
    }
    out
}

/// A Rust file's code before its unit tests, without comment lines.
fn code_of(path: &Path) -> String {
    std::fs::read_to_string(path)
        .expect("read")
        .split("#[cfg(test)]")
        .next()
        .unwrap_or_default()
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The imports between the files of a folder module (the `.rs` files beside its `mod.rs`): a
/// file imports a sibling when it names `super::sibling::…`, or through `super::` an item the
/// sibling defines (the folder's re-exports). `mod.rs`, which declares the files, and unit tests
/// are left out.
fn sibling_imports(dir: &Path) -> BTreeMap<String, std::collections::BTreeSet<String>> {
    let mut code = BTreeMap::new();
    for e in std::fs::read_dir(dir).expect("read_dir").flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let Some(m) = name.strip_suffix(".rs") else {
            continue;
        };
        if m == "mod" {
            continue;
        }
        code.insert(m.to_string(), code_of(&e.path()));
    }
    let ident = |s: &str| -> String {
        s.trim()
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect()
    };
    let mut owner = BTreeMap::new();
    for (m, text) in &code {
        for line in text.lines() {
            let mut l = line.trim_start();
            for vis in ["pub(crate) ", "pub(super) ", "pub "] {
                l = l.strip_prefix(vis).unwrap_or(l);
            }
            for kw in [
                "struct ", "enum ", "fn ", "trait ", "type ", "const ", "static ",
            ] {
                if let Some(rest) = l.strip_prefix(kw) {
                    owner.insert(ident(rest), m.clone());
                }
            }
        }
    }
    let mut out = BTreeMap::new();
    for (m, text) in &code {
        let uses: &mut std::collections::BTreeSet<String> = out.entry(m.clone()).or_default();
        for (at, _) in text.match_indices("super::") {
            let rest = &text[at + "super::".len()..];
            let names: Vec<String> = match rest.strip_prefix('{') {
                Some(group) => group
                    .split('}')
                    .next()
                    .unwrap_or_default()
                    .split(',')
                    .map(ident)
                    .collect(),
                None => vec![ident(rest)],
            };
            for n in names {
                let target = if code.contains_key(&n) {
                    Some(n)
                } else {
                    owner.get(&n).cloned()
                };
                if let Some(t) = target.filter(|t| t != m) {
                    uses.insert(t);
                }
            }
        }
    }
    out
}

#[test]
fn no_crate_has_modules_importing_each_other_in_a_circle() {
    let mut found = Vec::new();
    for group in ["tools", "viewer"] {
        for e in std::fs::read_dir(root().join(group))
            .expect("read")
            .flatten()
        {
            let src = e.path().join("src");
            if !src.is_dir() {
                continue;
            }
            for c in circles(&module_imports(&src)) {
                found.push(format!(
                    "{}: {}",
                    src.strip_prefix(root()).expect("inside").display(),
                    c.join(" ⇄ ")
                ));
            }
            // and the files of every folder module among themselves
            let mut dirs = vec![src.clone()];
            while let Some(dir) = dirs.pop() {
                for e in std::fs::read_dir(&dir).expect("read_dir").flatten() {
                    if e.path().is_dir() {
                        dirs.push(e.path());
                    }
                }
                if dir == src || !dir.join("mod.rs").is_file() {
                    continue;
                }
                for c in circles(&sibling_imports(&dir)) {
                    found.push(format!(
                        "{}: {}",
                        dir.strip_prefix(root()).expect("inside").display(),
                        c.join(" ⇄ ")
                    ));
                }
            }
        }
    }
    found.sort();
    assert!(found.is_empty(), "import circles:\n{}", found.join("\n"));
}
