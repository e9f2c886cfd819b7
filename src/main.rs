//! The `relight-cpc` command line: a thin shell over the library.

fn main() {
    println!("relight-cpc: under construction");
}
