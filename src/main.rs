//! The `meshmatch` binary: the desktop app (no arguments) and the command-line tools.

fn main() {
    std::process::exit(meshmatch::cli::main());
}
