//! A bare zenoh ping-pong with the co-simulation's session settings, for benchmarks.
//!
//! `pingpong pong --endpoint E` answers every ping with `--reply` bytes; `pingpong ping --endpoint E
//! --size S --seconds T` sends S-byte pings (as the plant sends states: router session, express,
//! blocking congestion control, callback into a channel) and prints round trips per second.
//! Both sides run unauthenticated, as a bare zenoh baseline.

use std::time::{Duration, Instant};

use crossbeam_channel::{bounded, Receiver};
use zenoh::qos::CongestionControl;
use zenoh::Wait;

use crawler_protocol::Role;
use crawler_transport::{Access, Network};

fn arg(args: &[String], name: &str, default: &str) -> String {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .cloned()
        .unwrap_or_else(|| default.to_string())
}

type Link = (
    zenoh::pubsub::Publisher<'static>,
    Receiver<Vec<u8>>,
    zenoh::pubsub::Subscriber<()>,
);

/// Publishes on `out` as the plant publishes states; `in_` arrives through a callback into a channel.
fn link(session: &zenoh::Session, out: &'static str, in_: &'static str) -> anyhow::Result<Link> {
    let z = |e: zenoh::Error| anyhow::anyhow!("{e}");
    let publisher = session
        .declare_publisher(out)
        .congestion_control(CongestionControl::Block)
        .express(true)
        .wait()
        .map_err(z)?;
    let (tx, rx) = bounded::<Vec<u8>>(1024);
    let sub = session
        .declare_subscriber(in_)
        .callback(move |s| {
            let _ = tx.try_send(s.payload().to_bytes().into_owned());
        })
        .wait()
        .map_err(z)?;
    Ok((publisher, rx, sub))
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let mode = args.get(1).cloned().unwrap_or_default();
    let endpoint = arg(&args, "--endpoint", "tcp/127.0.0.1:7999");
    let size: usize = arg(&args, "--size", "7300").parse()?;
    let reply: usize = arg(&args, "--reply", "120").parse()?;
    let seconds: f64 = arg(&args, "--seconds", "3").parse()?;
    let net = Network::loopback("pingpong", &endpoint)?;
    let z = |e: zenoh::Error| anyhow::anyhow!("{e}");
    match mode.as_str() {
        "ping" => {
            let session =
                crawler_transport::open(Role::Plant, &net, &Access::Open, size.max(reply))?;
            let (publisher, rx, _sub) = link(&session, "bench/ping", "bench/pong")?;
            let payload = vec![7u8; size];
            // wait for the pong side
            loop {
                publisher.put(payload.clone()).wait().map_err(z)?;
                if rx.recv_timeout(Duration::from_millis(200)).is_ok() {
                    break;
                }
            }
            while rx.try_recv().is_ok() {}
            let start = Instant::now();
            let mut n = 0u64;
            while start.elapsed().as_secs_f64() < seconds {
                publisher.put(payload.clone()).wait().map_err(z)?;
                rx.recv_timeout(Duration::from_secs(5))?;
                n += 1;
            }
            let t = start.elapsed().as_secs_f64();
            println!(
                "{{\"round_trips\":{n},\"seconds\":{t},\"per_second\":{}}}",
                n as f64 / t
            );
        }
        "pong" => {
            let session =
                crawler_transport::open(Role::Controller, &net, &Access::Open, size.max(reply))?;
            let (publisher, rx, _sub) = link(&session, "bench/pong", "bench/ping")?;
            let answer = vec![9u8; reply];
            while let Ok(_ping) = rx.recv_timeout(Duration::from_secs_f64(seconds + 10.0)) {
                publisher.put(answer.clone()).wait().map_err(z)?;
            }
        }
        _ => anyhow::bail!(
            "usage: pingpong ping|pong [--endpoint E] [--size S] [--reply R] [--seconds T]"
        ),
    }
    Ok(())
}
