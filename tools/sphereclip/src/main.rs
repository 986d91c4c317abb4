//! `sphereclip`: runs the commands that need no GDAL and hands the others to `sphereclip-gdal`
//! (see the library's documentation).

fn main() -> std::process::ExitCode {
    sphereclip::main(sphereclip::cmd::run_without_gdal)
}
