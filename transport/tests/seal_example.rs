//! The authentication example of `docs/protocol.md`: its derived keys, its envelope and its seal
//! are what this crate computes, so a controller written from that page interoperates.
//!
//! `PRINT_WIRE_EXAMPLES=1 cargo test --release -p crawler-transport --test seal_example -- --nocapture`
//! prints them (to refresh the document after a deliberate change of the protocol).

use std::path::PathBuf;

use crawler_protocol::{
    encode, Actuation, Header, ProcessId, Role, RunNonce, WaveMsg, PROTOCOL_VERSION,
};
use crawler_transport::credential::write_private;
use crawler_transport::gate::envelope;
use crawler_transport::{Credential, Seal};

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// 16 bytes per line: offset, hex bytes, printable ASCII (as `protocol/tests/wire_examples.rs`).
fn hexdump(bytes: &[u8]) -> String {
    let mut out = String::new();
    for (i, chunk) in bytes.chunks(16).enumerate() {
        let hex: Vec<String> = chunk.iter().map(|b| format!("{b:02x}")).collect();
        let ascii: String = chunk
            .iter()
            .map(|&b| {
                if (0x20..0x7f).contains(&b) {
                    b as char
                } else {
                    '.'
                }
            })
            .collect();
        out.push_str(&format!(
            "{:08x}  {:<47}  |{}|\n",
            i * 16,
            hex.join(" "),
            ascii
        ));
    }
    out
}

fn protocol_md() -> String {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf();
    std::fs::read_to_string(root.join("docs/protocol.md")).unwrap()
}

#[test]
fn the_documented_envelope_and_seal_are_the_ones_computed() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("credential");
    let secret: Vec<u8> = (0u8..32).collect();
    write_private(
        &path,
        format!("crawler-credential 1\nrun demo\nsecret {}\n", hex(&secret)).as_bytes(),
    )
    .unwrap();
    let c = Credential::load(&path, "demo").unwrap();
    // the documented actuation (a wave)
    let a = Actuation {
        v: PROTOCOL_VERSION,
        step: 3,
        controller: "c0ffee00c0ffee00".into(),
        wave: Some(WaveMsg {
            f0: 0.5,
            k: 6.25,
            omega: 74.0,
            phase: 0.0,
        }),
        field: None,
    };
    let payload = encode(&a);
    assert_eq!(payload.len(), 104);
    let key = "crawler/demo/actuation";
    let header = Header {
        run: RunNonce(std::array::from_fn(|i| 0xa0 + i as u8)),
        role: Role::Controller,
        sender: ProcessId::parse("c0ffee00c0ffee00").unwrap(),
        seq: 1,
    };
    let seal = Seal::new(&c.message_key());
    let att = envelope(Some(&seal), key, &header, &[], &payload);
    assert_eq!(att.len(), 42 + 32);
    let tag = &att[42..];
    let dump = hexdump(&att);
    if std::env::var_os("PRINT_WIRE_EXAMPLES").is_some() {
        println!("attachment:\n```text\n{dump}```\nseal {}", hex(tag));
    }
    let doc = protocol_md();
    assert!(
        doc.contains(&dump),
        "docs/protocol.md must show the attachment:\n{dump}"
    );
    assert!(
        doc.contains(&format!("is `{}`", hex(tag))),
        "docs/protocol.md must give the seal {}",
        hex(tag)
    );
    // and the derivations and the seal are the documented HMAC-SHA256 ones, recomputed
    // independently
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
    let meta = &att[..42];
    let mut expected_meta = vec![3u8, b'c'];
    expected_meta.extend(0xa0u8..0xb0);
    expected_meta.extend(b"c0ffee00c0ffee00");
    expected_meta.extend(1u64.to_le_bytes());
    assert_eq!(meta, expected_meta.as_slice());
    let mut m = <Hmac<sha2::Sha256> as Mac>::new_from_slice(&c.message_key()).unwrap();
    m.update(b"crawler seal 3\0");
    m.update(&(key.len() as u64).to_le_bytes());
    m.update(key.as_bytes());
    m.update(&(meta.len() as u64).to_le_bytes());
    m.update(meta);
    m.update(&payload);
    assert_eq!(m.finalize().into_bytes().to_vec(), tag.to_vec());
}
