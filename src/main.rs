//! The `splat2tiles` command line: a thin front over the library.
fn main() {
    println!("splat2tiles");
}
