use std::time::Instant;
fn main() {
    let dir = cetratus_bench::program::examples_dir().join("vernadat");
    let pn = dir.join("vernadat.pnml");
    let toml_path = dir.join("vernadat.toml");
    let text = std::fs::read_to_string(&pn).unwrap();
    let toml_text = std::fs::read_to_string(&toml_path).unwrap();
    let n = 2000;
    let t = Instant::now();
    for _ in 0..n {
        std::hint::black_box(std::fs::read_to_string(&pn).unwrap());
    }
    println!("read file {:?}", t.elapsed() / n);
    let t = Instant::now();
    for _ in 0..n {
        std::hint::black_box(roxmltree::Document::parse(&text).unwrap());
    }
    println!("roxmltree {:?}", t.elapsed() / n);
    let t = Instant::now();
    for _ in 0..n {
        std::hint::black_box(cetratus_net::pnml::read_str(&text, "x").unwrap());
    }
    println!("pnml read_str {:?}", t.elapsed() / n);
    let net = cetratus_net::pnml::read_str(&text, "x").unwrap();
    let t = Instant::now();
    for _ in 0..n {
        std::hint::black_box(
            cetratus_program::Program::from_sources(&toml_text, "x", net.clone()).unwrap(),
        );
    }
    println!("from_sources {:?}", t.elapsed() / n);
    let t = Instant::now();
    for _ in 0..n {
        std::hint::black_box(toml::from_str::<toml::Table>(&toml_text).unwrap());
    }
    println!("toml parse {:?}", t.elapsed() / n);
    println!("sizes pnml {} toml {}", text.len(), toml_text.len());
}
