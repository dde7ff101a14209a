//! Which connections `serve` keeps when it is full: every connection is registered with its
//! client address and phase; waiting ones (for a request head, or idle) can be evicted.
//!
//! When the connection cap is reached, a new connection evicts the longest-waiting connection of
//! the client address holding the most connections (per-IP fairness: one client opening many
//! slow connections loses its own first). Connections busy answering are never evicted; only
//! when every connection is busy does a newcomer get 503. One address may have at most a share
//! of the connections busy at once (a request beyond it gets 503), so clients of one address
//! that read slowly cannot take every connection from the others.

use std::net::{IpAddr, Shutdown, TcpStream};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// What a registered connection is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Waiting for (the rest of) a request head since this instant: evictable.
    Waiting(Instant),
    /// Answering a request.
    Busy,
}

#[derive(Debug)]
struct Entry {
    id: u64,
    ip: IpAddr,
    phase: Phase,
    /// A handle to the socket, to shut it down on eviction.
    stream: TcpStream,
}

#[derive(Debug, Default)]
struct Inner {
    next: u64,
    entries: Vec<Entry>,
    evicted: u64,
    /// Most connections of one address busy at once.
    per_address: usize,
}

/// What [`Ticket::busy`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// The connection may answer its request.
    Granted,
    /// It was evicted while its request head arrived (its socket is shut down).
    Evicted,
    /// Its address has its share of busy connections already: answer 503.
    OverShare,
}

/// The registry of live connections, shared by the accept loop and the connection threads.
#[derive(Debug, Clone)]
pub struct Admission {
    inner: Arc<Mutex<Inner>>,
    cap: usize,
}

/// A registered connection; unregisters itself when dropped.
#[derive(Debug)]
pub struct Ticket {
    inner: Arc<Mutex<Inner>>,
    id: u64,
}

impl Admission {
    /// A registry keeping at most `cap` connections, of which at most `per_address` of one
    /// client address busy at once.
    pub fn new(cap: usize, per_address: usize) -> Self {
        Admission {
            inner: Arc::new(Mutex::new(Inner {
                per_address: per_address.max(1),
                ..Inner::default()
            })),
            cap: cap.max(1),
        }
    }

    /// Registers `stream` from `ip` (in the waiting phase), evicting a waiting connection when
    /// full; `None` when every connection is busy (answer 503).
    pub fn admit(&self, ip: IpAddr, stream: &TcpStream) -> Option<Ticket> {
        let handle = stream.try_clone().ok()?;
        let mut g = self.inner.lock().unwrap_or_else(|p| p.into_inner());
        if g.entries.len() >= self.cap {
            let victim = pick_victim(&g.entries)?;
            let e = g.entries.swap_remove(victim);
            let _ = e.stream.shutdown(Shutdown::Both);
            g.evicted += 1;
        }
        let id = g.next;
        g.next += 1;
        g.entries.push(Entry {
            id,
            ip,
            phase: Phase::Waiting(Instant::now()),
            stream: handle,
        });
        Some(Ticket {
            inner: self.inner.clone(),
            id,
        })
    }

    /// Connections registered now.
    pub fn live(&self) -> usize {
        self.inner.lock().map(|g| g.entries.len()).unwrap_or(0)
    }

    /// Connections evicted so far.
    pub fn evicted(&self) -> u64 {
        self.inner.lock().map(|g| g.evicted).unwrap_or(0)
    }
}

/// The waiting connection to evict: of the address with the most connections, the one waiting
/// longest.
fn pick_victim(entries: &[Entry]) -> Option<usize> {
    let mut per_ip: std::collections::HashMap<IpAddr, usize> = std::collections::HashMap::new();
    for e in entries {
        *per_ip.entry(e.ip).or_default() += 1;
    }
    entries
        .iter()
        .enumerate()
        .filter_map(|(i, e)| match e.phase {
            Phase::Waiting(since) => Some((i, per_ip[&e.ip], since)),
            Phase::Busy => None,
        })
        // Most connections first, then the oldest wait.
        .min_by(|a, b| b.1.cmp(&a.1).then(a.2.cmp(&b.2)))
        .map(|(i, _, _)| i)
}

impl Ticket {
    fn set(&self, phase: Phase) {
        let mut g = self.inner.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(e) = g.entries.iter_mut().find(|e| e.id == self.id) {
            e.phase = phase;
        }
    }

    /// The connection waits for a request head (evictable).
    pub fn waiting(&self) {
        self.set(Phase::Waiting(Instant::now()));
    }

    /// The connection answers a request (not evictable), unless it was evicted already or its
    /// address has its share of busy connections (then it stays waiting).
    pub fn busy(&self) -> Start {
        let mut g = self.inner.lock().unwrap_or_else(|p| p.into_inner());
        let Some(at) = g.entries.iter().position(|e| e.id == self.id) else {
            return Start::Evicted;
        };
        let ip = g.entries[at].ip;
        let busy_here = g
            .entries
            .iter()
            .filter(|e| e.ip == ip && e.phase == Phase::Busy && e.id != self.id)
            .count();
        if busy_here >= g.per_address {
            return Start::OverShare;
        }
        g.entries[at].phase = Phase::Busy;
        Start::Granted
    }
}

impl Drop for Ticket {
    fn drop(&mut self) {
        let mut g = self.inner.lock().unwrap_or_else(|p| p.into_inner());
        g.entries.retain(|e| e.id != self.id);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpListener;

    #[test]
    fn full_registry_evicts_the_busiest_addresses_oldest_waiter_and_spares_busy_ones() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = l.local_addr().unwrap();
        let conns: Vec<TcpStream> = (0..4).map(|_| TcpStream::connect(addr).unwrap()).collect();
        let a = Admission::new(3, 3);
        let ip_a: IpAddr = "10.0.0.1".parse().unwrap();
        let ip_b: IpAddr = "10.0.0.2".parse().unwrap();
        let t0 = a.admit(ip_a, &conns[0]).unwrap();
        let t1 = a.admit(ip_a, &conns[1]).unwrap();
        let t2 = a.admit(ip_b, &conns[2]).unwrap();
        assert_eq!(t0.busy(), Start::Granted);
        // Full: the newcomer evicts ip_a's waiting connection (ip_a holds the most), not ip_b's.
        let t3 = a.admit(ip_b, &conns[3]).unwrap();
        assert_eq!(a.evicted(), 1);
        assert_eq!(t1.busy(), Start::Evicted, "t1 was evicted");
        assert_eq!((t2.busy(), t3.busy()), (Start::Granted, Start::Granted));
        // Everything busy: no room.
        assert!(a.admit(ip_b, &conns[3]).is_none());
        drop((t0, t2));
        assert_eq!(a.live(), 1);
    }

    #[test]
    fn one_address_gets_its_share_of_busy_connections_and_no_more() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = l.local_addr().unwrap();
        let conns: Vec<TcpStream> = (0..4).map(|_| TcpStream::connect(addr).unwrap()).collect();
        let a = Admission::new(8, 2);
        let (ip_a, ip_b): (IpAddr, IpAddr) =
            ("10.0.0.1".parse().unwrap(), "10.0.0.2".parse().unwrap());
        let t: Vec<Ticket> = (0..3).map(|i| a.admit(ip_a, &conns[i]).unwrap()).collect();
        assert_eq!(t[0].busy(), Start::Granted);
        assert_eq!(t[1].busy(), Start::Granted);
        assert_eq!(t[2].busy(), Start::OverShare);
        // Another address is not held back; a finished answer frees a share.
        let b = a.admit(ip_b, &conns[3]).unwrap();
        assert_eq!(b.busy(), Start::Granted);
        t[0].waiting();
        assert_eq!(t[2].busy(), Start::Granted);
    }
}
