//! The plans' share of the processor: their simulation work (rehearsals, drives among the
//! fleet) runs at most one job per core, and a free core goes to the job of the plan that was
//! asked first.
//!
//! Left to the blocking pool, twenty plans asked at once each get a twentieth of the cores and
//! all of them answer late, near when the last one does (processor sharing); a plan driven
//! against a schedule read early also commits late, and more often meets plans committed
//! meanwhile and is driven again. Served oldest first, the first plans answer in a few of
//! their own drive times and the last no later than before.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use tokio::sync::oneshot;

/// Hands out one core per job, the oldest plan's first ([`CpuGate::acquire`]).
#[derive(Debug)]
pub(crate) struct CpuGate {
    state: Mutex<State>,
    tickets: AtomicU64,
}

#[derive(Debug)]
struct State {
    free: usize,
    /// Jobs waiting, by (plan ticket, arrival): the smallest first.
    waiting: BinaryHeap<Reverse<Waiter>>,
    arrivals: u64,
}

#[derive(Debug)]
struct Waiter {
    order: (u64, u64),
    wake: oneshot::Sender<()>,
}

impl PartialEq for Waiter {
    fn eq(&self, other: &Self) -> bool {
        self.order == other.order
    }
}
impl Eq for Waiter {}
impl PartialOrd for Waiter {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Waiter {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.order.cmp(&other.order)
    }
}

/// A core held; given back when dropped.
#[derive(Debug)]
pub(crate) struct Permit {
    gate: Arc<CpuGate>,
}

impl Drop for Permit {
    fn drop(&mut self) {
        self.gate.release();
    }
}

/// A wait for a core that, dropped (the plan abandoned) after one was handed to it, gives it on.
struct Pending {
    gate: Arc<CpuGate>,
    wake: Option<oneshot::Receiver<()>>,
}

impl Drop for Pending {
    fn drop(&mut self) {
        if let Some(mut rx) = self.wake.take() {
            rx.close();
            if rx.try_recv().is_ok() {
                self.gate.release();
            }
        }
    }
}

impl CpuGate {
    /// A gate of `cores` (at least 1).
    pub(crate) fn new(cores: usize) -> Arc<Self> {
        Arc::new(Self {
            state: Mutex::new(State {
                free: cores.max(1),
                waiting: BinaryHeap::new(),
                arrivals: 0,
            }),
            tickets: AtomicU64::new(0),
        })
    }

    /// A gate of this machine's cores.
    pub(crate) fn of_this_machine() -> Arc<Self> {
        Self::new(std::thread::available_parallelism().map_or(1, usize::from))
    }

    /// The next plan's place in line: plans asked earlier hold smaller tickets.
    pub(crate) fn ticket(&self) -> u64 {
        self.tickets.fetch_add(1, Ordering::Relaxed)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// A core for a job of the plan holding `ticket`: at once if one is free, else when the
    /// jobs of every older plan waiting have had theirs. Cancel-safe.
    pub(crate) async fn acquire(self: &Arc<Self>, ticket: u64) -> Permit {
        loop {
            let rx = {
                let mut s = self.lock();
                // A core is free only while nobody waits: a freed one goes to a waiter first.
                if s.free > 0 {
                    s.free -= 1;
                    return Permit {
                        gate: Arc::clone(self),
                    };
                }
                let (tx, rx) = oneshot::channel();
                let order = (ticket, s.arrivals);
                s.arrivals += 1;
                s.waiting.push(Reverse(Waiter { order, wake: tx }));
                rx
            };
            let mut pending = Pending {
                gate: Arc::clone(self),
                wake: Some(rx),
            };
            let woken = match pending.wake.as_mut() {
                Some(rx) => rx.await.is_ok(),
                None => false,
            };
            pending.wake = None;
            if woken {
                return Permit {
                    gate: Arc::clone(self),
                };
            }
        }
    }

    /// Whether a plan waits for a core, or none is free: work done in idle time gives way.
    pub(crate) fn busy(&self) -> bool {
        let s = self.lock();
        s.free == 0 || !s.waiting.is_empty()
    }

    fn release(&self) {
        let mut s = self.lock();
        hand_on(&mut s);
    }
}

/// Gives a core (just freed) to the oldest waiting job still waiting, else back to the pool.
fn hand_on(s: &mut State) {
    while let Some(Reverse(w)) = s.waiting.pop() {
        if w.wake.send(()).is_ok() {
            return;
        }
    }
    s.free += 1;
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[tokio::test]
    async fn a_freed_core_goes_to_the_oldest_plan_waiting() {
        let gate = CpuGate::new(1);
        let held = gate.acquire(5).await;
        let order = Arc::new(Mutex::new(Vec::new()));
        let mut tasks = Vec::new();
        // Asked in the order 9, 3, 7: served 3, 7, 9.
        for ticket in [9u64, 3, 7] {
            let (gate, order) = (Arc::clone(&gate), Arc::clone(&order));
            tasks.push(tokio::spawn(async move {
                let _p = gate.acquire(ticket).await;
                order.lock().unwrap().push(ticket);
                tokio::time::sleep(Duration::from_millis(5)).await;
            }));
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        assert!(
            order.lock().unwrap().is_empty(),
            "nobody runs while the core is held"
        );
        drop(held);
        for t in tasks {
            t.await.unwrap();
        }
        assert_eq!(*order.lock().unwrap(), vec![3, 7, 9]);
    }

    #[tokio::test]
    async fn an_abandoned_wait_gives_its_core_on() {
        let gate = CpuGate::new(1);
        let held = gate.acquire(0).await;
        // A plan abandoned while it waits (its request dropped) takes no core with it.
        let abandoned = tokio::time::timeout(Duration::from_millis(10), gate.acquire(1)).await;
        assert!(abandoned.is_err());
        drop(held);
        let again = tokio::time::timeout(Duration::from_millis(500), gate.acquire(2)).await;
        assert!(again.is_ok(), "the core came back to the gate");
        drop(again);
        // Cores never multiply: two held at once only from a gate of two.
        let two = CpuGate::new(2);
        let (_a, _b) = (two.acquire(0).await, two.acquire(0).await);
        let third = tokio::time::timeout(Duration::from_millis(10), two.acquire(0)).await;
        assert!(third.is_err());
    }
}
