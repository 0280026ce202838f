//! The run's credential: a 256-bit secret shared by the processes of one run, in a file only its
//! user can read.
//!
//! From the secret two keys are derived (HMAC-SHA256 with distinct labels and the run id):
//! - the **transport password**: zenoh's user/password authentication (`auth_usrpwd`). The plant
//!   accepts only sessions that prove they know it (zenoh's challenge-response: the password
//!   never crosses the link), so a process without the credential cannot even connect;
//! - the **message key**: every message of the run carries an HMAC-SHA256 seal under it
//!   ([`crate::seal`]), so whoever relays messages without holding the key (a shared zenoh
//!   router, or a session that knows only the transport password) can neither forge nor alter
//!   one.
//!
//! The file (text, three lines):
//!
//! ```text
//! crawler-credential 1
//! run <run id>
//! secret <64 hex digits>
//! ```
//!
//! It is created with mode 0600 (written to a fresh file, then renamed into place) and read only
//! if it is a regular file owned by this user that group and others cannot access.

use std::io::{Read, Write};
use std::os::unix::fs::{MetadataExt, OpenOptionsExt, PermissionsExt};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _};
use hmac::{Hmac, Mac};
use sha2::Sha256;

use crawler_protocol::validate_run_id;

/// First line of a credential file.
const MAGIC: &str = "crawler-credential 1";

/// The zenoh user name of every process of a run.
pub const ZENOH_USER: &str = "crawler";

/// Largest credential file read, bytes (a valid one is under 200).
const MAX_FILE: u64 = 4096;

/// A run's secret.
#[derive(Clone)]
pub struct Credential {
    run: String,
    secret: [u8; 32],
    path: PathBuf,
}

impl std::fmt::Debug for Credential {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Credential(run {}, {})", self.run, self.path.display())
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn unhex(s: &str) -> Option<Vec<u8>> {
    if !s.len().is_multiple_of(2) || !s.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).ok())
        .collect()
}

impl Credential {
    /// A fresh credential for `run_id` (256 bits from the operating system's random source),
    /// to be saved at `path`.
    pub fn generate(run_id: &str, path: &Path) -> anyhow::Result<Self> {
        validate_run_id(run_id)?;
        let mut secret = [0u8; 32];
        getrandom::fill(&mut secret)
            .map_err(|e| anyhow::anyhow!("no random numbers from the operating system: {e}"))?;
        Ok(Self {
            run: run_id.to_string(),
            secret,
            path: path.to_path_buf(),
        })
    }

    /// The run this credential belongs to.
    pub fn run(&self) -> &str {
        &self.run
    }

    /// Where it is stored.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn derive(&self, label: &str) -> [u8; 32] {
        let mut mac = <Hmac<Sha256> as Mac>::new_from_slice(&self.secret)
            .expect("HMAC takes a key of any length");
        mac.update(label.as_bytes());
        mac.update(&[0]);
        mac.update(self.run.as_bytes());
        mac.finalize().into_bytes().into()
    }

    /// The zenoh password of the run (64 hex digits).
    pub fn transport_password(&self) -> String {
        hex(&self.derive("crawler transport password 1"))
    }

    /// The key of the run's message seals.
    pub fn message_key(&self) -> [u8; 32] {
        self.derive("crawler message key 1")
    }

    /// The file's text.
    fn text(&self) -> String {
        format!("{MAGIC}\nrun {}\nsecret {}\n", self.run, hex(&self.secret))
    }

    /// Writes the credential to its path with mode 0600: a fresh file in the same directory,
    /// renamed over any earlier one (a reader never sees a partial file).
    pub fn save(&self) -> anyhow::Result<()> {
        write_private(&self.path, self.text().as_bytes())
            .with_context(|| format!("cannot write the credential {}", self.path.display()))
    }

    /// Reads the credential at `path` for run `run_id`: refused unless it is a regular file owned
    /// by this user, not accessible to group or others, well-formed and for that run.
    pub fn load(path: &Path, run_id: &str) -> anyhow::Result<Self> {
        let text = read_private(path)?;
        let bad = |line: usize, what: &str| {
            anyhow::anyhow!("invalid credential {} line {line}: {what}", path.display())
        };
        let mut lines = text.lines();
        if lines.next() != Some(MAGIC) {
            return Err(bad(1, &format!("expected {MAGIC:?}")));
        }
        let run = lines
            .next()
            .and_then(|l| l.strip_prefix("run "))
            .ok_or_else(|| bad(2, "expected \"run <run id>\""))?;
        validate_run_id(run).map_err(|e| bad(2, &e.to_string()))?;
        let secret = lines
            .next()
            .and_then(|l| l.strip_prefix("secret "))
            .and_then(unhex)
            .and_then(|v| <[u8; 32]>::try_from(v).ok())
            .ok_or_else(|| bad(3, "expected \"secret <64 hex digits>\""))?;
        if lines.any(|l| !l.trim().is_empty()) {
            return Err(bad(4, "unexpected text after the secret"));
        }
        if run != run_id {
            bail!(
                "the credential {} is for run {run}, not for run {run_id}",
                path.display()
            );
        }
        Ok(Self {
            run: run.to_string(),
            secret,
            path: path.to_path_buf(),
        })
    }

    /// Writes zenoh's user/password dictionary for this run (one line, `crawler:<password>`)
    /// to `path`, mode 0600: the file the plant's session checks connecting sessions against.
    pub fn save_zenoh_users(&self, path: &Path) -> anyhow::Result<()> {
        let line = format!("{ZENOH_USER}:{}\n", self.transport_password());
        write_private(path, line.as_bytes())
            .with_context(|| format!("cannot write the zenoh user file {}", path.display()))
    }
}

/// Writes `bytes` to `path` through a fresh 0600 file renamed into place.
pub fn write_private(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty());
    let dir = dir.unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .ok_or_else(|| anyhow::anyhow!("{} is not a file name", path.display()))?;
    let mut nonce = [0u8; 8];
    getrandom::fill(&mut nonce).map_err(|e| anyhow::anyhow!("{e}"))?;
    let tmp = dir.join(format!(".{}.{}", name.to_string_lossy(), hex(&nonce)));
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(&tmp)?;
    let written = f.write_all(bytes).and_then(|()| f.sync_all());
    drop(f);
    if let Err(e) = written.and_then(|()| std::fs::rename(&tmp, path)) {
        let _ = std::fs::remove_file(&tmp);
        return Err(e.into());
    }
    Ok(())
}

/// Reads a small private file: a regular file (not a link) owned by this user, mode without any
/// permission for group or others.
pub fn read_private(path: &Path) -> anyhow::Result<String> {
    let f = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NOFOLLOW)
        .open(path)
        .with_context(|| format!("cannot open the credential {}", path.display()))?;
    let meta = f.metadata()?;
    if !meta.is_file() {
        bail!("the credential {} is not a regular file", path.display());
    }
    let uid = crate::runtime_dir::euid();
    if meta.uid() != uid {
        bail!(
            "the credential {} belongs to user id {}, not to this user ({uid}): refusing it",
            path.display(),
            meta.uid()
        );
    }
    let mode = meta.permissions().mode() & 0o777;
    if mode & 0o077 != 0 {
        bail!(
            "the credential {} has mode {mode:03o}: it must be readable by its owner only \
             (chmod 600 it)",
            path.display()
        );
    }
    if meta.len() > MAX_FILE {
        bail!(
            "the credential {} is {} bytes: not a credential",
            path.display(),
            meta.len()
        );
    }
    let mut text = String::new();
    f.take(MAX_FILE)
        .read_to_string(&mut text)
        .with_context(|| format!("the credential {} is not text", path.display()))?;
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_saved_credential_loads_back_private_and_for_its_run_only() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("credential");
        let c = Credential::generate("r1", &path).unwrap();
        c.save().unwrap();
        let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        let back = Credential::load(&path, "r1").unwrap();
        assert_eq!(back.secret, c.secret);
        assert_eq!(back.transport_password(), c.transport_password());
        assert_eq!(back.message_key(), c.message_key());
        // the two keys differ from each other and from the secret, and depend on the run
        assert_ne!(c.transport_password(), hex(&c.message_key()));
        assert_ne!(c.message_key(), c.secret);
        let other = Credential {
            run: "r2".into(),
            ..c.clone()
        };
        assert_ne!(other.message_key(), c.message_key());
        // two fresh credentials differ
        let d = Credential::generate("r1", &path).unwrap();
        assert_ne!(d.secret, c.secret);
        // another run's id: refused
        let e = Credential::load(&path, "r2").unwrap_err().to_string();
        assert!(e.contains("for run r1, not for run r2"), "{e}");
        // readable by others: refused
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
        let e = Credential::load(&path, "r1").unwrap_err().to_string();
        assert!(e.contains("mode 644"), "{e}");
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
        // a symbolic link: refused
        let link = tmp.path().join("link");
        std::os::unix::fs::symlink(&path, &link).unwrap();
        assert!(Credential::load(&link, "r1").is_err());
        // malformed: refused, naming the line
        for (text, line) in [
            ("nonsense\n", "line 1"),
            ("crawler-credential 1\nrun r1\nsecret 00\n", "line 3"),
            ("crawler-credential 1\nrun a/b\nsecret 00\n", "line 2"),
            ("crawler-credential 1\nrun r1\n", "line 3"),
        ] {
            write_private(&path, text.as_bytes()).unwrap();
            let e = Credential::load(&path, "r1").unwrap_err().to_string();
            assert!(e.contains(line), "{text:?}: {e}");
        }
    }

    #[test]
    fn the_zenoh_user_file_holds_the_transport_password_only() {
        let tmp = tempfile::tempdir().unwrap();
        let c = Credential::generate("r1", &tmp.path().join("credential")).unwrap();
        let users = tmp.path().join("users");
        c.save_zenoh_users(&users).unwrap();
        let text = std::fs::read_to_string(&users).unwrap();
        assert_eq!(text, format!("crawler:{}\n", c.transport_password()));
        assert!(!text.contains(&hex(&c.secret)));
        let mode = std::fs::metadata(&users).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
    }
}
