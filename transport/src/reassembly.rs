//! Messages that zenoh itself drops because they are larger than what a link reassembles
//! (`transport.link.rx.max_message_size`, the run's largest legal message plus a little): no
//! callback ever sees them, so no gate can count them. They are counted here instead, from
//! zenoh's own trace event for that drop ("Defragmentation buffer full"): [`count`] installs a
//! tracing subscriber that is enabled for that one call site of zenoh's receiving code and for
//! nothing else, so every other trace of zenoh stays off and costs a cached check.
//!
//! zenoh is pinned (`=1.10.2`), and the call site is found by its file and line; a test
//! (`tests/reassembly.rs`) floods a session with oversized messages and checks that they are
//! counted, so an upgrade that moves the call site fails there instead of counting nothing.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;

use tracing_core::field::{Field, Visit};
use tracing_core::span::{Attributes, Id, Record};
use tracing_core::{Event, Interest, Level, LevelFilter, Metadata, Subscriber};

/// Messages dropped while reassembling so far (in this process).
static DROPPED: AtomicU64 = AtomicU64::new(0);

/// The trace event zenoh 1.10.2 emits when a fragmented message grows past the link's limit
/// (`zenoh-transport/src/unicast/universal/rx.rs`, `tracing::trace!("{}", e)`).
const TARGET: &str = "zenoh_transport::unicast::universal::rx";
const FILE_SUFFIX: &str = "unicast/universal/rx.rs";
const LINE: u32 = 192;
const MESSAGE: &str = "Defragmentation buffer full";

fn is_drop_site(m: &Metadata<'_>) -> bool {
    m.is_event()
        && *m.level() == Level::TRACE
        && m.target() == TARGET
        && m.line() == Some(LINE)
        && m.file().is_some_and(|f| f.ends_with(FILE_SUFFIX))
}

struct Counter;

struct StartsWith(bool);

impl Visit for StartsWith {
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            self.0 = format!("{value:?}").starts_with(MESSAGE);
        }
    }
}

impl Subscriber for Counter {
    fn register_callsite(&self, m: &'static Metadata<'static>) -> Interest {
        if is_drop_site(m) {
            Interest::always()
        } else {
            Interest::never()
        }
    }

    fn enabled(&self, m: &Metadata<'_>) -> bool {
        is_drop_site(m)
    }

    fn max_level_hint(&self) -> Option<LevelFilter> {
        Some(LevelFilter::TRACE)
    }

    fn new_span(&self, _: &Attributes<'_>) -> Id {
        // never enabled for a span, but an id must be given
        Id::from_u64(1)
    }

    fn record(&self, _: &Id, _: &Record<'_>) {}

    fn record_follows_from(&self, _: &Id, _: &Id) {}

    fn event(&self, event: &Event<'_>) {
        let mut v = StartsWith(false);
        event.record(&mut v);
        if v.0 {
            DROPPED.fetch_add(1, Ordering::Relaxed);
        }
    }

    fn enter(&self, _: &Id) {}

    fn exit(&self, _: &Id) {}
}

/// Starts counting (once per process; every session opener calls it). False if the process
/// already had another tracing subscriber, which then decides what is traced: nothing is
/// counted.
pub fn count() -> bool {
    static INSTALLED: OnceLock<bool> = OnceLock::new();
    *INSTALLED.get_or_init(|| {
        tracing_core::dispatcher::set_global_default(tracing_core::Dispatch::new(Counter)).is_ok()
    })
}

/// Messages zenoh dropped in this process because they were larger than its links reassemble.
pub fn dropped() -> u64 {
    DROPPED.load(Ordering::Relaxed)
}
