//! Composes the WGSL of every pipeline from the WESL modules in `shaders/` (imports resolved,
//! `@if` features chosen, names kept as written): `$OUT_DIR/<artifact>.wgsl`, which `lib.rs`
//! includes.

use wesl::{CompileOptions, ManglerKind, Wesl};

/// Each artifact: its name, the root module, the features set.
const ARTIFACTS: [(&str, &str, &[&str]); 9] = [
    ("clipmap", "clipmap", &[]),
    ("clipmap_webgl", "clipmap", &["webgl"]),
    ("cdlod", "cdlod", &[]),
    ("cdlod_webgl", "cdlod", &["webgl"]),
    ("warp", "warp", &[]),
    ("atmosphere", "atmosphere", &["tables_written"]),
    ("transform_probe", "transform_probe", &["probe"]),
    ("cdlod_probe", "cdlod_probe", &["probe"]),
    ("warp_probe", "warp_probe", &["probe"]),
];

fn main() {
    let shaders = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shaders");
    println!("cargo:rerun-if-changed={shaders}");
    let out = std::path::PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets it"));
    for (name, root, features) in ARTIFACTS {
        let mut compiler = Wesl::new(shaders);
        // one namespace across the modules (no name is declared twice), so the entry points and
        // every name keep the spelling the Rust side and the tests use
        compiler.set_mangler(ManglerKind::None);
        compiler.set_options(CompileOptions {
            strip: false,
            ..Default::default()
        });
        for f in ["webgl", "tables_written", "probe"] {
            compiler.set_feature(f, features.contains(&f));
        }
        let path = format!("package::{root}").parse().expect("a module path");
        let wgsl = compiler
            .compile(&path)
            .unwrap_or_else(|e| panic!("shaders/{root}.wesl ({name}): {e}"));
        std::fs::write(out.join(format!("{name}.wgsl")), wgsl.to_string())
            .expect("write the composed shader");
    }
}
