//! Time to seal and to verify one message of each size (the authentication's CPU cost per
//! message). Usage: cargo run --release -p crawler-transport --example seal_cost
use crawler_transport::Seal;
use std::time::Instant;
fn main() {
    let seal = Seal::new(&[7u8; 32]);
    println!("| payload (B) | seal (us) | verify (us) |");
    println!("| ---: | ---: | ---: |");
    for size in [106usize, 7301, 115_000] {
        let payload = vec![0x5au8; size];
        let key = "crawler/bench/state";
        let n = (20_000_000 / size).max(100);
        let t = Instant::now();
        let mut tag = [0u8; 32];
        for _ in 0..n {
            tag = seal.seal(key, &[3u8; 42], std::hint::black_box(&payload));
        }
        let s = t.elapsed().as_secs_f64() / n as f64;
        let t = Instant::now();
        let mut ok = true;
        for _ in 0..n {
            ok &= seal.verify(key, &[3u8; 42], std::hint::black_box(&payload), &tag);
        }
        let v = t.elapsed().as_secs_f64() / n as f64;
        assert!(ok);
        println!("| {size} | {:.2} | {:.2} |", s * 1e6, v * 1e6);
    }
}
