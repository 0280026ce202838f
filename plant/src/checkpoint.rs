//! Checkpoints of a co-simulation run: everything needed to resume it bit-identically.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crawler_protocol::Rejections;

use crawler_physics::framing;
use crawler_physics::plant::{Plant, PlantState};
use crawler_physics::report::EpisodeLog;
use crawler_physics::scenario::Scenario;
use crawler_physics::task::TaskTracker;

const MAGIC: &[u8; 8] = b"CRWLCKPT";
const VERSION: u32 = 3;

/// Largest checkpoint file, bytes (a plant of the most cells with a long episode log is far
/// smaller).
pub const MAX_CHECKPOINT_BYTES: u64 = 1 << 30;

/// A stopped run: the plant's full state at the start of communication step `state.macro_step`
/// (no actuation for that step applied yet), and the run's bookkeeping.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint {
    /// Run id.
    pub run_id: String,
    /// The scenario the plant was built from.
    pub scenario: Scenario,
    /// The run ends at this communication step.
    pub last_step: u64,
    /// The plant's state.
    pub state: PlantState,
    /// Episodes recorded for the report so far.
    pub log: EpisodeLog,
    /// Actuation rejected so far.
    pub rejections: Rejections,
    /// Why the run stopped.
    pub reason: String,
    /// The run's progress against its task.
    pub task: TaskTracker,
}

impl Checkpoint {
    /// The bytes of the checkpoint file.
    pub fn to_bytes(&self) -> Vec<u8> {
        framing::encode(MAGIC, VERSION, self)
    }

    /// Writes the checkpoint atomically (a temporary file renamed over `path`), creating its
    /// directory if needed.
    pub fn save(&self, path: &Path) -> anyhow::Result<()> {
        let bytes = self.to_bytes();
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| {
                anyhow::anyhow!(
                    "cannot create the checkpoint's directory {}: {e}",
                    dir.display()
                )
            })?;
        }
        let tmp = path.with_extension("ckpt.tmp");
        std::fs::write(&tmp, &bytes)
            .map_err(|e| anyhow::anyhow!("cannot write checkpoint {}: {e}", tmp.display()))?;
        std::fs::rename(&tmp, path)
            .map_err(|e| anyhow::anyhow!("cannot write checkpoint {}: {e}", path.display()))?;
        Ok(())
    }

    /// Reads and checks a checkpoint (format, checksum, consistency of state and scenario).
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let bytes = framing::read_at_most(path, MAX_CHECKPOINT_BYTES)
            .map_err(|e| anyhow::anyhow!("cannot read checkpoint {}: {e}", path.display()))?;
        Self::from_bytes(&bytes)
            .map_err(|e| anyhow::anyhow!("invalid checkpoint {}: {e:#}", path.display()))
    }

    /// Decodes and checks the bytes of a checkpoint file.
    pub fn from_bytes(bytes: &[u8]) -> anyhow::Result<Self> {
        let c: Checkpoint = framing::decode(MAGIC, VERSION, "crawler checkpoint", bytes)?;
        crawler_protocol::validate_run_id(&c.run_id)?;
        c.scenario.validate()?;
        if c.state.params != c.scenario.plant {
            anyhow::bail!("the plant state does not belong to its scenario");
        }
        if c.state.macro_step > c.last_step {
            anyhow::bail!(
                "step {} is past the last step {}",
                c.state.macro_step,
                c.last_step
            );
        }
        // The state's values are validated when the plant is restored from it.
        Plant::from_state(&c.state)?;
        c.task.validate()?;
        Ok(c)
    }
}
