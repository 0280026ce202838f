//! Messages larger than what a link reassembles never reach a callback: zenoh drops them while
//! reassembling. They are counted all the same (`crawler_transport::reassembly`), from zenoh's
//! own trace of that drop: this test sends such messages and finds them counted, so a zenoh whose
//! trace moved fails here instead of counting nothing.

use std::time::{Duration, Instant};

use zenoh::Wait;

use crawler_protocol::Role;
use crawler_transport::{loopback_config_json, reassembly, Access, Network};

#[test]
fn messages_beyond_the_links_limit_are_counted_as_dropped() {
    let dir = tempfile::tempdir().unwrap();
    let endpoint = format!("unixsock-stream/{}/z.sock", dir.path().display());
    let net = Network::loopback("reassembly", &endpoint).unwrap();
    let limit = 64 << 10;
    let open = |role| {
        let json = loopback_config_json(role, &net, &Access::Open, limit);
        // `config` installs the counter; the test builds its configurations the same way
        let _ = crawler_transport::config(role, &net, &Access::Open, limit).unwrap();
        zenoh::open(zenoh::Config::from_json5(&json).unwrap())
            .wait()
            .unwrap()
    };
    assert!(
        reassembly::count(),
        "another tracing subscriber was installed first"
    );
    let router = open(Role::Plant);
    let received = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
    let r2 = received.clone();
    let _sub = router
        .declare_subscriber("crawler/reassembly/state")
        .callback(move |_| {
            r2.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        })
        .wait()
        .unwrap();
    let client = open(Role::Controller);
    let before = reassembly::dropped();
    let deadline = Instant::now() + Duration::from_secs(30);
    let mut sent = 0;
    while reassembly::dropped() < before + 3 && Instant::now() < deadline {
        // blocking: a put under congestion (a loaded machine) would otherwise drop the rest of
        // the message at the sender, which then never reaches the reassembly to be counted
        client
            .put("crawler/reassembly/state", vec![0u8; 4 * limit])
            .congestion_control(zenoh::qos::CongestionControl::Block)
            .wait()
            .unwrap();
        sent += 1;
        std::thread::sleep(Duration::from_millis(50));
    }
    let dropped = reassembly::dropped() - before;
    assert!(
        dropped >= 3,
        "{sent} oversized messages sent, {dropped} counted as dropped"
    );
    assert!(dropped <= sent, "{dropped} counted for {sent} sent");
    // a message within the limit still arrives (sent until one does: the subscription may
    // reach the client after its first puts)
    let deadline = Instant::now() + Duration::from_secs(30);
    while received.load(std::sync::atomic::Ordering::Relaxed) == 0 && Instant::now() < deadline {
        client
            .put("crawler/reassembly/state", vec![0u8; 100])
            .congestion_control(zenoh::qos::CongestionControl::Block)
            .wait()
            .unwrap();
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(received.load(std::sync::atomic::Ordering::Relaxed) > 0);
}
