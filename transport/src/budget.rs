//! Inboxes bounded in bytes: a payload is queued only if the bytes already queued plus its own
//! stay within the budget, or if nothing is queued (so a message larger than the whole budget,
//! which the arrival gate's size limit allows, still gets through one at a time), and its bytes
//! are released when the consumer drops it. An inbox therefore never holds more than the larger
//! of its budget and one message. The count of messages is bounded too, since each one is
//! charged a fixed overhead on top of its length.

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;

/// Bytes charged per message on top of its payload (the queue slot and the allocation).
pub const OVERHEAD: usize = 64;

/// A byte budget shared by the producers and the consumer of one inbox.
#[derive(Debug, Clone)]
pub struct ByteBudget {
    used: Arc<AtomicUsize>,
    cap: usize,
    overflow: Arc<AtomicU64>,
}

/// A value holding part of a budget until it is dropped.
#[derive(Debug)]
pub struct Charged<T> {
    value: T,
    charge: Charge,
}

impl<T> Charged<T> {
    /// The value.
    pub fn get(&self) -> &T {
        &self.value
    }

    /// Splits into the value and a guard that keeps the bytes charged until it is dropped.
    pub fn split(self) -> (T, Charge) {
        (self.value, self.charge)
    }
}

impl<T> std::ops::Deref for Charged<T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.value
    }
}

/// Bytes of a budget held until dropped.
#[derive(Debug)]
pub struct Charge {
    bytes: usize,
    used: Arc<AtomicUsize>,
}

impl Drop for Charge {
    fn drop(&mut self) {
        self.used.fetch_sub(self.bytes, Ordering::AcqRel);
    }
}

impl ByteBudget {
    /// A budget of `cap` bytes.
    pub fn new(cap: usize) -> Self {
        Self {
            used: Arc::default(),
            cap,
            overflow: Arc::default(),
        }
    }

    /// Charges `len` bytes (plus [`OVERHEAD`]) for `value`; `None` (and one more overflow
    /// counted) if that would exceed the budget while something else is charged.
    pub fn charge<T>(&self, value: T, len: usize) -> Option<Charged<T>> {
        let bytes = len.saturating_add(OVERHEAD);
        let mut used = self.used.load(Ordering::Acquire);
        loop {
            let next = used.saturating_add(bytes);
            if next > self.cap && used > 0 {
                self.overflow.fetch_add(1, Ordering::Relaxed);
                return None;
            }
            match self
                .used
                .compare_exchange_weak(used, next, Ordering::AcqRel, Ordering::Acquire)
            {
                Ok(_) => {
                    return Some(Charged {
                        value,
                        charge: Charge {
                            bytes,
                            used: self.used.clone(),
                        },
                    })
                }
                Err(now) => used = now,
            }
        }
    }

    /// Bytes charged now.
    pub fn used(&self) -> usize {
        self.used.load(Ordering::Acquire)
    }

    /// The budget, bytes.
    pub fn cap(&self) -> usize {
        self.cap
    }

    /// Messages refused so far because the budget was spent.
    pub fn overflow(&self) -> u64 {
        self.overflow.load(Ordering::Relaxed)
    }

    /// The shared overflow counter.
    pub fn overflow_counter(&self) -> &Arc<AtomicU64> {
        &self.overflow
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_budget_refuses_beyond_its_bytes_and_recovers_when_consumed() {
        let b = ByteBudget::new(1000);
        let a = b.charge(vec![0u8; 400], 400).unwrap();
        let c = b.charge(vec![0u8; 400], 400).unwrap();
        assert_eq!(b.used(), 2 * (400 + OVERHEAD));
        assert!(b.charge(vec![0u8; 100], 100).is_none());
        assert_eq!(b.overflow(), 1);
        drop(a);
        assert_eq!(b.used(), 400 + OVERHEAD);
        let (v, guard) = c.split();
        assert_eq!(v.len(), 400);
        assert_eq!(b.used(), 400 + OVERHEAD);
        drop(guard);
        assert_eq!(b.used(), 0);
        // empty messages are charged their overhead: the count is bounded too
        let held: Vec<_> = (0..100).map_while(|_| b.charge((), 0)).collect();
        assert_eq!(held.len(), 1000 / OVERHEAD);
    }

    #[test]
    fn a_message_larger_than_the_budget_passes_alone_and_only_alone() {
        let b = ByteBudget::new(1000);
        let small = b.charge((), 10).unwrap();
        assert!(
            b.charge((), 5000).is_none(),
            "queued beside another message"
        );
        assert_eq!(b.overflow(), 1);
        drop(small);
        let big = b
            .charge((), 5000)
            .expect("an empty inbox takes one message of any size");
        assert_eq!(b.used(), 5000 + OVERHEAD);
        assert!(
            b.charge((), 0).is_none(),
            "nothing joins an inbox beyond its budget"
        );
        assert!(b.charge((), 5000).is_none());
        assert_eq!(b.overflow(), 3);
        drop(big);
        assert_eq!(b.used(), 0);
        assert!(b.charge((), 5000).is_some());
    }
}
