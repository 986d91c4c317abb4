//! `sphereclip-gdal`: every command, those that open rasters through GDAL included. Users call
//! `sphereclip`, which runs this for them.

fn main() -> std::process::ExitCode {
    sphereclip::main(sphereclip::cmd::run)
}
