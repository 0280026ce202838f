//! Key expressions of a run: everything lives under `crawler/<run-id>/`.

use crate::error::ProtocolError;

/// Root of every key.
pub const ROOT: &str = "crawler";

/// Longest run id accepted.
pub const MAX_RUN_ID_LEN: usize = 64;

/// The roles that declare liveliness tokens.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// The physics plant (owns the clock).
    Plant,
    /// The controller answering each state with an actuation.
    Controller,
    /// The recorder.
    Bridge,
}

impl Role {
    /// Every role.
    pub const ALL: [Role; 3] = [Role::Plant, Role::Controller, Role::Bridge];

    /// The role's name in keys and in [`crate::Status::role`].
    pub fn as_str(self) -> &'static str {
        match self {
            Role::Plant => "plant",
            Role::Controller => "controller",
            Role::Bridge => "bridge",
        }
    }

    /// The role named `name` (`"plant"`, `"controller"` or `"bridge"`).
    pub fn parse(name: &str) -> Option<Role> {
        Role::ALL.into_iter().find(|r| r.as_str() == name)
    }
}

wire_name!(
    Role,
    "status.role",
    "\"plant\", \"controller\" or \"bridge\""
);

/// Checks a run id: 1 to 64 characters from `[A-Za-z0-9_-]` (no key-expression wildcards).
pub fn validate_run_id(id: &str) -> Result<(), ProtocolError> {
    let ok = !id.is_empty()
        && id.len() <= MAX_RUN_ID_LEN
        && id
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-');
    if ok {
        Ok(())
    } else {
        Err(ProtocolError::Invalid {
            field: "run_id".into(),
            value: format!("{id:?}"),
            allowed: format!("1 to {MAX_RUN_ID_LEN} characters from A-Z a-z 0-9 _ -"),
        })
    }
}

/// The keys of one run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunKeys {
    run: String,
}

impl RunKeys {
    /// Keys for `run` (validated).
    pub fn new(run: &str) -> Result<Self, ProtocolError> {
        validate_run_id(run)?;
        Ok(Self {
            run: run.to_string(),
        })
    }

    /// The run id.
    pub fn run(&self) -> &str {
        &self.run
    }

    fn key(&self, leaf: &str) -> String {
        format!("{ROOT}/{}/{leaf}", self.run)
    }

    /// Plant → controller, bridge: [`crate::State`] each communication step.
    pub fn state(&self) -> String {
        self.key("state")
    }

    /// Controller → plant: [`crate::Actuation`] answering each state.
    pub fn actuation(&self) -> String {
        self.key("actuation")
    }

    /// Controller → plant: [`crate::Join`], a request to control the run (or take it over).
    pub fn join(&self) -> String {
        self.key("join")
    }

    /// Plant → bridge: [`crate::Events`], stick-slip episodes that ended in a step.
    pub fn events(&self) -> String {
        self.key("events")
    }

    /// Plant → bridge: [`crate::Metrics`] of each completed forcing period.
    pub fn metrics(&self) -> String {
        self.key("metrics")
    }

    /// Controller → bridge: [`crate::Prediction`] of the models for the applied wave.
    pub fn prediction(&self) -> String {
        self.key("prediction")
    }

    /// Any process → all: [`crate::Status`] of `role`.
    pub fn status(&self, role: Role) -> String {
        self.key(&format!("status/{}", role.as_str()))
    }

    /// Statuses of every role (wildcard).
    pub fn status_all(&self) -> String {
        self.key("status/*")
    }

    /// Queryable of the plant: [`crate::ModelInfo`].
    pub fn model(&self) -> String {
        self.key("model")
    }

    /// Queryable of the plant, for the recorder: [`crate::Environment`], the pipe's friction as
    /// the plant resolved it (also when controllers are not told it).
    pub fn environment(&self) -> String {
        self.key("environment")
    }

    /// Liveliness token of one process of `role`, identified by `id`.
    pub fn alive(&self, role: Role, id: &str) -> String {
        self.key(&format!("alive/{}/{id}", role.as_str()))
    }

    /// Liveliness tokens of every process of `role` (wildcard).
    pub fn alive_all(&self, role: Role) -> String {
        self.key(&format!("alive/{}/*", role.as_str()))
    }

    /// Every key of the run (wildcard).
    pub fn all(&self) -> String {
        self.key("**")
    }

    /// The id at the end of a liveliness key of this run, if it is one of `role`.
    pub fn id_of_alive_key<'a>(&self, role: Role, key: &'a str) -> Option<&'a str> {
        let prefix = format!("{ROOT}/{}/alive/{}/", self.run, role.as_str());
        key.strip_prefix(prefix.as_str())
            .filter(|id| !id.is_empty() && !id.contains('/'))
    }
}
