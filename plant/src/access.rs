//! The plant's side of a run's authentication: it owns the credential (a fresh one unless the
//! user named an existing file), writes zenoh's user file for its router session, and removes
//! what it created when it exits.

use std::path::PathBuf;

use crawler_transport::{runtime_dir, Access, Auth, Credential, Network, Seal};

/// What the plant's session presents and checks, and what it removes at exit.
#[derive(Debug)]
pub struct PlantAccess {
    /// How the plant's session checks connecting sessions.
    pub access: Access,
    /// The run's message seals (`None`: unauthenticated run).
    pub seal: Option<Seal>,
    /// The credential, when the run is authenticated.
    pub credential: Option<Credential>,
    /// Files created here, removed on drop.
    created: Vec<PathBuf>,
    /// The run's private directory, removed on drop if empty.
    run_dir: Option<PathBuf>,
    /// This plant's hold on the run id (released first on drop).
    claim: Option<runtime_dir::RunClaim>,
}

impl PlantAccess {
    /// Prepares the run's authentication in `network`: creates the run's private directory; a
    /// fresh credential at the default path (replacing any earlier one), or the one named by
    /// `--credential` (created if missing); and zenoh's user file in the private directory.
    pub fn prepare(network: &Network) -> anyhow::Result<Self> {
        // first of all: no other plant runs this run id (nothing of its is touched otherwise)
        let claim = runtime_dir::claim(&network.run_id)?;
        let uses_run_dir = network.config_file.is_none()
            && network.endpoint == crawler_transport::default_endpoint(&network.run_id);
        let mut me = Self {
            access: Access::Open,
            seal: None,
            credential: None,
            created: Vec::new(),
            run_dir: None,
            claim: Some(claim),
        };
        let Auth::Credential { path, explicit } = &network.auth else {
            if uses_run_dir {
                me.run_dir = Some(runtime_dir::ensure_run_dir(&network.run_id)?);
            }
            return Ok(me);
        };
        let dir = runtime_dir::ensure_run_dir(&network.run_id)?;
        me.run_dir = Some(dir.clone());
        let existing = *explicit && std::fs::symlink_metadata(path).is_ok();
        let credential = if existing {
            Credential::load(path, &network.run_id)?
        } else {
            let c = Credential::generate(&network.run_id, path)?;
            c.save()?;
            if !*explicit {
                me.created.push(path.clone());
            }
            c
        };
        if network.config_file.is_none() {
            let users = dir.join("zenoh-users");
            credential.save_zenoh_users(&users)?;
            me.created.push(users.clone());
            me.access = Access::Users(users);
        }
        me.seal = Some(Seal::new(&credential.message_key()));
        me.credential = Some(credential);
        Ok(me)
    }
}

impl Drop for PlantAccess {
    fn drop(&mut self) {
        drop(self.claim.take());
        for f in &self.created {
            let _ = std::fs::remove_file(f);
        }
        if let Some(d) = &self.run_dir {
            // only if empty (a socket or a user's file keeps it)
            let _ = std::fs::remove_dir(d);
        }
    }
}
