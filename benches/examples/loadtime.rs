//! Profiling aid: loads the Vernadat program many times (run it under callgrind or perf).
fn main() {
    let path = cetratus_bench::program::examples_dir().join("vernadat/vernadat.toml");
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(200);
    let t = std::time::Instant::now();
    for _ in 0..n {
        std::hint::black_box(cetratus_program::Program::load(&path).expect("loads"));
    }
    println!("Program::load {:?}", t.elapsed() / n as u32);
}
