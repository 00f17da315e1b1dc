//! Launch the desktop app: `cargo run --release --example gui [SOURCE TARGET [CORR.json]]`.
//! With no arguments it opens the procedural zebra -> giraffe demo scene.

fn main() {
    let args: Vec<std::path::PathBuf> = std::env::args_os().skip(1).map(Into::into).collect();
    let startup = meshmatch::app::Startup {
        source: args.first().cloned(),
        target: args.get(1).cloned(),
        correspondences: args.get(2).cloned(),
    };
    if let Err(e) = meshmatch::app::run(startup) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
