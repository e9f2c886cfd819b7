//! Stable-toolchain fuzz driver: bounded-time random mutation of a seed corpus.
//!
//! `mutate TARGET SECONDS SEED CORPUS_FILE...` — each iteration takes a corpus file
//! (prefixed by a random selector byte for the COLMAP targets), applies 1–8 random edits
//! (byte overwrite, insertion of random or "interesting" bytes, deletion, block copy,
//! truncation) and runs the target under `catch_unwind`. A panic writes the input to
//! `artifacts/TARGET/crash-N` and makes the exit status 1; an input taking over 2 s is
//! written as `slow-N`. Prints the number of executions and findings at the end.

use std::panic;
use std::path::PathBuf;
use std::time::{Duration, Instant};

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        // xorshift64*
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const INTERESTING: &[&[u8]] = &[
    &[0xff; 8],
    &[0xff, 0xff, 0xff, 0x7f],
    &[0, 0, 0, 0x80],
    &[0, 0, 0xc0, 0x7f],
    b" nan ",
    b" -1 ",
    b" 1e999 ",
    b" 18446744073709551616 ",
    b"\n",
    b"#",
    b"element vertex 4294967295\n",
    b"property list uchar int vertex_indices\n",
];

fn mutate(rng: &mut Rng, b: &mut Vec<u8>) {
    for _ in 0..1 + rng.below(8) {
        let n = b.len();
        match rng.below(6) {
            0 if n > 0 => {
                let i = rng.below(n);
                b[i] = rng.next() as u8;
            }
            1 => {
                let at = rng.below(n + 1);
                let ins: Vec<u8> = if rng.below(2) == 0 {
                    INTERESTING[rng.below(INTERESTING.len())].to_vec()
                } else {
                    (0..1 + rng.below(8)).map(|_| rng.next() as u8).collect()
                };
                b.splice(at..at, ins);
            }
            2 if n > 0 => {
                let at = rng.below(n);
                let len = 1 + rng.below(16);
                b.drain(at..(at + len).min(n));
            }
            3 if n > 0 => {
                let from = rng.below(n);
                let len = (1 + rng.below(32)).min(n - from);
                let chunk = b[from..from + len].to_vec();
                let to = rng.below(n + 1);
                b.splice(to..to, chunk);
            }
            4 if n > 0 => b.truncate(rng.below(n)),
            _ if n > 0 => {
                let i = rng.below(n);
                b[i] ^= 1 << rng.below(8);
            }
            _ => {}
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 || !relight_cpc_fuzz::TARGETS.contains(&args[1].as_str()) {
        eprintln!(
            "usage: mutate {{{}}} SECONDS SEED [CORPUS_FILE...]",
            relight_cpc_fuzz::TARGETS.join("|")
        );
        std::process::exit(2);
    }
    let target = args[1].clone();
    let secs: u64 = args[2].parse().unwrap_or(60);
    let mut rng = Rng(args[3].parse::<u64>().unwrap_or(1).max(1));
    let mut corpus: Vec<Vec<u8>> = args[4..]
        .iter()
        .filter_map(|p| std::fs::read(p).ok())
        .collect();
    if corpus.is_empty() {
        corpus.push(Vec::new());
    }
    let out = PathBuf::from("artifacts").join(&target);
    let _ = std::fs::create_dir_all(&out);
    panic::set_hook(Box::new(|_| {}));
    let colmap = target.starts_with("colmap");
    let end = Instant::now() + Duration::from_secs(secs);
    let (mut execs, mut crashes, mut slow) = (0u64, 0u64, 0u64);
    while Instant::now() < end {
        let mut input = corpus[rng.below(corpus.len())].clone();
        mutate(&mut rng, &mut input);
        if colmap {
            input.insert(0, rng.next() as u8);
        }
        let t = Instant::now();
        let r = panic::catch_unwind(|| relight_cpc_fuzz::run_target(&target, &input));
        execs += 1;
        if r.is_err() {
            crashes += 1;
            let _ = std::fs::write(out.join(format!("crash-{crashes}")), &input);
        } else if t.elapsed() > Duration::from_secs(2) {
            slow += 1;
            let _ = std::fs::write(out.join(format!("slow-{slow}")), &input);
        }
    }
    println!("{target}: {execs} executions in {secs} s, {crashes} crashes, {slow} slow inputs");
    std::process::exit(i32::from(crashes > 0));
}
