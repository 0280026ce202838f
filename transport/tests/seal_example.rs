//! The authentication example of `docs/protocol.md`: its derived keys and its seal are what this
//! crate computes, so a controller written from that page interoperates.

use std::path::PathBuf;

use crawler_protocol::{encode, Actuation, WaveMsg, PROTOCOL_VERSION};
use crawler_transport::credential::write_private;
use crawler_transport::{Credential, Seal};

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn protocol_md() -> String {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf();
    std::fs::read_to_string(root.join("docs/protocol.md")).unwrap()
}

#[test]
fn the_documented_seal_is_the_one_computed() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("credential");
    let secret: Vec<u8> = (0u8..32).collect();
    write_private(
        &path,
        format!("crawler-credential 1\nrun demo\nsecret {}\n", hex(&secret)).as_bytes(),
    )
    .unwrap();
    let c = Credential::load(&path, "demo").unwrap();
    // the documented actuation (a wave, 94 bytes)
    let a = Actuation {
        v: PROTOCOL_VERSION,
        step: 3,
        controller: "c0ffee".into(),
        wave: Some(WaveMsg {
            f0: 0.5,
            k: 6.25,
            omega: 74.0,
            phase: 0.0,
        }),
        field: None,
    };
    let payload = encode(&a);
    assert_eq!(payload.len(), 94);
    let seal = Seal::new(&c.message_key()).seal("crawler/demo/actuation", &payload);
    let doc = protocol_md();
    assert!(
        doc.contains(&format!("is `{}`", hex(&seal))),
        "docs/protocol.md must give the seal {}",
        hex(&seal)
    );
    // and the derivations are the documented HMAC-SHA256 ones, recomputed independently
    use hmac::{Hmac, Mac};
    let derive = |label: &str| {
        let mut m = <Hmac<sha2::Sha256> as Mac>::new_from_slice(&secret).unwrap();
        m.update(label.as_bytes());
        m.update(&[0]);
        m.update(b"demo");
        m.finalize().into_bytes().to_vec()
    };
    assert_eq!(
        c.transport_password(),
        hex(&derive("crawler transport password 1"))
    );
    assert_eq!(c.message_key().to_vec(), derive("crawler message key 1"));
    let mut m = <Hmac<sha2::Sha256> as Mac>::new_from_slice(&c.message_key()).unwrap();
    m.update(b"crawler seal 1\0");
    m.update(&(b"crawler/demo/actuation".len() as u64).to_le_bytes());
    m.update(b"crawler/demo/actuation");
    m.update(&payload);
    assert_eq!(m.finalize().into_bytes().to_vec(), seal.to_vec());
}
