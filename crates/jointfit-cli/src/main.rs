//! The `jointfit` command-line tool.

fn main() {
    println!("jointfit {}", env!("CARGO_PKG_VERSION"));
}
