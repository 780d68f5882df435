//! A UDP endpoint that can misbehave on purpose: each datagram it sends may be dropped,
//! corrupted (one byte flipped, so the CRC fails), delayed, or swapped with the next one.
//! Seeded: the same faults for the same seed. The faults themselves ([`FaultQueue`]) serve the
//! DDS endpoint too.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::net::{SocketAddr, UdpSocket};

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Faults {
    /// Probability that a datagram is lost.
    pub drop_prob: f64,
    /// Probability that one byte of a datagram is flipped.
    pub corrupt_prob: f64,
    /// Every datagram leaves this much later, s.
    pub delay_s: f64,
    /// Probability that a datagram is held back and sent after the next one.
    pub reorder_prob: f64,
    pub seed: u64,
}

impl Faults {
    pub fn validate(&self, who: &str) -> Result<(), String> {
        for (name, p) in [
            ("drop_prob", self.drop_prob),
            ("corrupt_prob", self.corrupt_prob),
            ("reorder_prob", self.reorder_prob),
        ] {
            if !(0.0..=1.0).contains(&p) {
                return Err(format!(
                    "{who} {name} = {p} is out of range: allowed [0, 1]"
                ));
            }
        }
        if !(0.0..=1.0).contains(&self.delay_s) {
            return Err(format!(
                "{who} delay_s = {} is out of range: allowed [0, 1] s",
                self.delay_s
            ));
        }
        Ok(())
    }
}

/// Counters of one endpoint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct LinkStats {
    pub sent: usize,
    pub dropped: usize,
    pub corrupted: usize,
    pub reordered: usize,
    pub received: usize,
    /// DDS: samples dropped because their writer announced another type name than the topic's
    /// (RustDDS matches writers to readers by topic name alone), or was never announced.
    pub wrong_type: usize,
}

/// The faults of one sending side, for any transport: what to lose, damage, delay or hold
/// back, and the messages waiting for their time (with where each goes, `T`).
pub struct FaultQueue<T> {
    faults: Faults,
    rng: ChaCha8Rng,
    /// Messages waiting for their time: (release time, bytes, destination).
    queue: VecDeque<(f64, Vec<u8>, T)>,
    held: Option<(Vec<u8>, T)>,
}

impl<T> FaultQueue<T> {
    pub fn new(faults: Faults) -> Self {
        FaultQueue {
            rng: ChaCha8Rng::seed_from_u64(faults.seed),
            faults,
            queue: VecDeque::new(),
            held: None,
        }
    }

    /// Takes one message at `now_s`: drops, damages, holds back or queues it.
    pub fn push(&mut self, bytes: &[u8], to: T, now_s: f64, stats: &mut LinkStats) {
        let f = &self.faults;
        if f.drop_prob > 0.0 && self.rng.random::<f64>() < f.drop_prob {
            stats.dropped += 1;
            return;
        }
        let mut bytes = bytes.to_vec();
        if f.corrupt_prob > 0.0 && self.rng.random::<f64>() < f.corrupt_prob && !bytes.is_empty() {
            let i = self.rng.random_range(0..bytes.len());
            bytes[i] ^= 0x5A;
            stats.corrupted += 1;
        }
        if f.reorder_prob > 0.0 && self.held.is_none() && self.rng.random::<f64>() < f.reorder_prob
        {
            self.held = Some((bytes, to));
            stats.reordered += 1;
            return;
        }
        let release = now_s + f.delay_s;
        self.queue.push_back((release, bytes, to));
        if let Some((b, t)) = self.held.take() {
            self.queue.push_back((release, b, t));
        }
    }

    /// The next message due by `now_s`.
    pub fn pop_due(&mut self, now_s: f64) -> Option<(Vec<u8>, T)> {
        match self.queue.front() {
            Some((t, _, _)) if *t <= now_s => self.queue.pop_front().map(|(_, b, to)| (b, to)),
            _ => None,
        }
    }
}

pub struct Link {
    socket: UdpSocket,
    queue: FaultQueue<SocketAddr>,
    pub stats: LinkStats,
    buf: Vec<u8>,
}

impl Link {
    pub fn bind(addr: SocketAddr, faults: Faults) -> Result<Self, String> {
        faults.validate("faults")?;
        let socket = UdpSocket::bind(addr).map_err(|e| format!("cannot bind UDP {addr}: {e}"))?;
        socket
            .set_nonblocking(true)
            .map_err(|e| format!("UDP {addr}: {e}"))?;
        Ok(Link {
            socket,
            queue: FaultQueue::new(faults),
            stats: LinkStats::default(),
            buf: vec![0; 2048],
        })
    }

    pub fn local_addr(&self) -> SocketAddr {
        self.socket.local_addr().expect("bound")
    }

    /// Sends (or, by the faults, loses, damages, delays or holds back) one datagram at `now_s`.
    pub fn send(&mut self, bytes: &[u8], to: SocketAddr, now_s: f64) {
        self.queue.push(bytes, to, now_s, &mut self.stats);
        self.flush(now_s);
    }

    /// Sends what is due by `now_s`.
    pub fn flush(&mut self, now_s: f64) {
        while let Some((b, to)) = self.queue.pop_due(now_s) {
            // A full socket buffer or an unreachable peer loses the datagram, as UDP does.
            if self.socket.send_to(&b, to).is_ok() {
                self.stats.sent += 1;
            }
        }
    }

    /// The next datagram waiting, if any (never blocks).
    pub fn recv(&mut self) -> Option<(Vec<u8>, SocketAddr)> {
        match self.socket.recv_from(&mut self.buf) {
            Ok((n, from)) => {
                self.stats.received += 1;
                Some((self.buf[..n].to_vec(), from))
            }
            Err(_) => None,
        }
    }
}
