//! # crawler-controller
//!
//! The controller program's library: [`client`], a policy driving a co-simulated plant over
//! zenoh (joining the run, answering each state once, publishing predictions for the recorder).
//! The models are `crawler-models`, the policies `crawler-policies`, the figures
//! `crawler-figures`; [`cli`] is the program's command line (`main.rs` calls it).

pub mod cli;
pub mod client;
