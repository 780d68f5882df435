//! The Go2's low-level DDS interface on RustDDS: `rt/lowcmd` (`unitree_go::msg::dds_::LowCmd_`,
//! controller → robot) and `rt/lowstate` (`LowState_`, robot → controller), on a domain (0 the
//! robot, 1 Unitree's simulator) and optionally one network interface.
//!
//! Samples travel as their CDR bytes: the DDS layer copies them in and out without looking
//! ([`RawCdr`]), and eemp-core's codec decodes them in the runner, so a malformed or
//! bad-CRC message from the network is a counted, dropped message there, never an error inside
//! the middleware. QoS follows Cyclone DDS's defaults (unitree_sdk2 passes none): the writer
//! RELIABLE, the reader BEST_EFFORT (matches a peer writer of either kind), both KEEP_LAST 1
//! and VOLATILE — a controller only ever wants the newest state, a robot the newest command.

use crate::link::{FaultQueue, Faults, LinkStats};
use crate::wire::go2_idl::{CDR_LE_HEADER, LOW_CMD_TYPE_NAME, LOW_STATE_TYPE_NAME};
use rustdds::bytes::Bytes;
use rustdds::no_key::{
    DataReader, DataWriter, Decode, DefaultDecoder, DeserializerAdapter, SerializerAdapter,
};
use rustdds::policy::{Durability, History, Reliability};
use rustdds::{
    DataWriterStatus, DomainParticipant, DomainParticipantBuilder, DomainParticipantStatusEvent,
    DomainParticipantStatusListener, QosPolicies, QosPolicyBuilder, RepresentationIdentifier,
    StatusEvented, TopicKind, GUID,
};
use std::collections::HashMap;
use std::net::IpAddr;

pub const TOPIC_LOWCMD: &str = "rt/lowcmd";
pub const TOPIC_LOWSTATE: &str = "rt/lowstate";
/// The largest domain id the RTPS port mapping allows (7400 + 250·d + … below 65536).
pub const MAX_DOMAIN_ID: u16 = 232;
/// Unitree's simulator (and `eemp sim-robot --link dds`) runs on domain 1, the robot on 0.
pub const SIM_DOMAIN_ID: u16 = 1;
pub const ROBOT_DOMAIN_ID: u16 = 0;

/// Where to speak DDS.
#[derive(Clone, Debug, PartialEq)]
pub struct DdsConfig {
    pub domain_id: u16,
    /// A network interface name (`enp3s0`, `lo`): only its addresses are used for discovery
    /// and multicast. None: every interface.
    pub iface: Option<String>,
}

impl DdsConfig {
    pub fn validate(&self) -> Result<(), String> {
        if self.domain_id > MAX_DOMAIN_ID {
            return Err(format!(
                "DDS domain {} is out of range: allowed 0..={MAX_DOMAIN_ID} (0: the robot, 1: Unitree's simulator)",
                self.domain_id
            ));
        }
        if let Some(name) = &self.iface {
            interface_addresses(name)?;
        }
        Ok(())
    }

    /// "domain 1 on lo", for messages.
    pub fn describe(&self) -> String {
        format!(
            "domain {} on {}",
            self.domain_id,
            self.iface.as_deref().unwrap_or("every interface")
        )
    }

    /// A participant on this domain and interface.
    pub fn participant(&self) -> Result<DomainParticipant, String> {
        self.validate()?;
        let mut b = DomainParticipantBuilder::new(self.domain_id);
        if let Some(name) = &self.iface {
            b = b.with_only_networks(interface_addresses(name)?);
        }
        b.build().map_err(|e| {
            format!(
                "cannot start a DDS participant on domain {}: {e}",
                self.domain_id
            )
        })
    }
}

/// The IP addresses of interface `name`; an unknown name (or one without an address) is an
/// error that lists the interfaces there are.
pub fn interface_addresses(name: &str) -> Result<Vec<IpAddr>, String> {
    let all = netdev::get_interfaces();
    let Some(iface) = all.iter().find(|i| i.name == name) else {
        let names: Vec<&str> = all.iter().map(|i| i.name.as_str()).collect();
        return Err(format!(
            "network interface '{name}' does not exist: allowed {}",
            names.join(", ")
        ));
    };
    let addrs: Vec<IpAddr> = iface
        .ipv4
        .iter()
        .map(|n| IpAddr::V4(n.addr()))
        .chain(iface.ipv6.iter().map(|n| IpAddr::V6(n.addr())))
        .collect();
    if addrs.is_empty() {
        return Err(format!("network interface '{name}' has no IP address"));
    }
    Ok(addrs)
}

/// One sample's CDR bytes, encapsulation header included (as eemp-core's codec reads them).
#[derive(Clone, Debug, PartialEq)]
pub struct CdrBytes(pub Vec<u8>);

/// Passes CDR bytes through RustDDS untouched: RustDDS writes the encapsulation header from
/// [`SerializerAdapter::output_encoding`] and hands the reader the bytes after it, so the
/// header is taken off here on the way out and put back on the way in.
pub struct RawCdr;

#[derive(Debug, thiserror::Error)]
pub enum RawCdrError {
    #[error("a CDR sample must start with the CDR_LE header 00 01 00 00, got {0:02x?}")]
    Header(Vec<u8>),
}

impl SerializerAdapter<CdrBytes> for RawCdr {
    type Error = RawCdrError;
    fn output_encoding() -> RepresentationIdentifier {
        RepresentationIdentifier::CDR_LE
    }
    fn to_bytes(value: &CdrBytes) -> Result<Bytes, RawCdrError> {
        match value.0.get(..4) {
            Some(h) if h == CDR_LE_HEADER => Ok(Bytes::copy_from_slice(&value.0[4..])),
            _ => Err(RawCdrError::Header(
                value.0.iter().take(4).copied().collect(),
            )),
        }
    }
}

impl DeserializerAdapter<CdrBytes> for RawCdr {
    type Error = RawCdrError;
    type Decoded = CdrBytes;
    fn supported_encodings() -> &'static [RepresentationIdentifier] {
        // Only little endian, plain: XCDR1 or XCDR2 (a peer may pick either for a `final`
        // type; the bodies of these types are the same in both, see go2_idl). A big-endian
        // peer's samples are not delivered, which the runner sees as silence.
        &[
            RepresentationIdentifier::CDR_LE,
            RepresentationIdentifier::XCDR2_LE,
        ]
    }
    fn transform_decoded(decoded: CdrBytes) -> CdrBytes {
        decoded
    }
}

#[derive(Clone)]
pub struct RawCdrDecoder;

impl Decode<'_, CdrBytes> for RawCdrDecoder {
    type Error = RawCdrError;
    fn decode_bytes(
        self,
        input: &[u8],
        encoding: RepresentationIdentifier,
    ) -> Result<CdrBytes, RawCdrError> {
        let mut out = Vec::with_capacity(4 + input.len());
        out.extend_from_slice(&encoding.to_bytes());
        out.extend_from_slice(&[0, 0]);
        out.extend_from_slice(input);
        Ok(CdrBytes(out))
    }
}

impl DefaultDecoder<CdrBytes> for RawCdr {
    type Decoder = RawCdrDecoder;
    const DECODER: RawCdrDecoder = RawCdrDecoder;
}

/// Cyclone DDS's default writer QoS (what unitree_sdk2 gets with qos = None).
pub fn writer_qos() -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(Reliability::Reliable {
            max_blocking_time: rustdds::Duration::from_millis(100),
        })
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 1 })
        .build()
}

/// Best effort: matches a reliable or a best-effort writer; a late sample is worthless here.
pub fn reader_qos() -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(Reliability::BestEffort)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 1 })
        .build()
}

/// The no-key topic `topic` of type `type_name` (its QoS: Cyclone's default writer's).
fn raw_topic(
    participant: &DomainParticipant,
    topic: &str,
    type_name: &str,
) -> Result<rustdds::Topic, String> {
    participant
        .create_topic(
            topic.into(),
            type_name.into(),
            &writer_qos(),
            TopicKind::NoKey,
        )
        .map_err(|e| format!("cannot create DDS topic {topic}: {e}"))
}

/// A writer of raw CDR samples on `topic` (type `type_name`), reliable as Cyclone's default.
pub fn raw_writer(
    participant: &DomainParticipant,
    topic: &str,
    type_name: &str,
) -> Result<DataWriter<CdrBytes, RawCdr>, String> {
    let t = raw_topic(participant, topic, type_name)?;
    participant
        .create_publisher(&writer_qos())
        .map_err(|e| format!("cannot create a DDS publisher: {e}"))?
        .create_datawriter_no_key::<CdrBytes, RawCdr>(&t, Some(writer_qos()))
        .map_err(|e| format!("cannot create a DDS writer on {topic}: {e}"))
}

/// A reader of raw CDR samples on `topic` with `qos`.
pub fn raw_reader(
    participant: &DomainParticipant,
    topic: &str,
    type_name: &str,
    qos: QosPolicies,
) -> Result<DataReader<CdrBytes, RawCdr>, String> {
    let t = raw_topic(participant, topic, type_name)?;
    participant
        .create_subscriber(&qos)
        .map_err(|e| format!("cannot create a DDS subscriber: {e}"))?
        .create_datareader_no_key::<CdrBytes, RawCdr>(&t, Some(qos))
        .map_err(|e| format!("cannot create a DDS reader on {topic}: {e}"))
}

/// Which side of the low-level interface an endpoint plays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// Writes `rt/lowcmd`, reads `rt/lowstate` (`eemp hw`).
    Controller,
    /// Writes `rt/lowstate`, reads `rt/lowcmd` (the robot, `eemp sim-robot`).
    Robot,
}

/// One side of the Go2 low-level interface, with the fault injection of the UDP link on what
/// it writes (a corrupted sample has a byte of its CDR flipped, so its CRC fails).
pub struct Go2Endpoint {
    // Dropped last: the writer and reader need their participant.
    writer: DataWriter<CdrBytes, RawCdr>,
    reader: DataReader<CdrBytes, RawCdr>,
    queue: FaultQueue<()>,
    pub stats: LinkStats,
    /// Samples the middleware could not hand over (a reader error).
    pub read_errors: usize,
    /// The writers discovered on the topic read, and whether their type name is the expected.
    writer_types: HashMap<GUID, bool>,
    in_topic: &'static str,
    in_type: &'static str,
    status: DomainParticipantStatusListener,
    matched: usize,
    where_: String,
    participant: DomainParticipant,
}

impl Go2Endpoint {
    pub fn new(cfg: &DdsConfig, role: Role, faults: Faults) -> Result<Self, String> {
        faults.validate("dds")?;
        let participant = cfg.participant()?;
        let (out_name, out_type, in_name, in_type) = match role {
            Role::Controller => (
                TOPIC_LOWCMD,
                LOW_CMD_TYPE_NAME,
                TOPIC_LOWSTATE,
                LOW_STATE_TYPE_NAME,
            ),
            Role::Robot => (
                TOPIC_LOWSTATE,
                LOW_STATE_TYPE_NAME,
                TOPIC_LOWCMD,
                LOW_CMD_TYPE_NAME,
            ),
        };
        // Before any reader exists, so no writer's discovery can be missed.
        let status = participant.status_listener();
        let writer = raw_writer(&participant, out_name, out_type)?;
        let reader = raw_reader(&participant, in_name, in_type, reader_qos())?;
        Ok(Go2Endpoint {
            writer,
            reader,
            queue: FaultQueue::new(faults),
            stats: LinkStats::default(),
            read_errors: 0,
            writer_types: HashMap::new(),
            in_topic: in_name,
            in_type,
            status,
            matched: 0,
            where_: cfg.describe(),
            participant,
        })
    }

    /// Its participant (another service can live on it, as the robot's motion switcher).
    pub fn participant(&self) -> &DomainParticipant {
        &self.participant
    }

    /// Domain and interface, for messages.
    pub fn describe(&self) -> &str {
        &self.where_
    }

    /// Readers on the other side that this endpoint's writer has matched (discovery done).
    pub fn matched_readers(&mut self) -> usize {
        while let Some(status) = self.writer.try_recv_status() {
            if let DataWriterStatus::PublicationMatched { current, .. } = status {
                self.matched = current.count().max(0) as usize;
            }
        }
        self.matched
    }

    /// Writes (or, by the faults, loses, damages, delays or holds back) one sample at `now_s`.
    pub fn send(&mut self, cdr: &[u8], now_s: f64) {
        self.queue.push(cdr, (), now_s, &mut self.stats);
        self.flush(now_s);
    }

    /// Writes what is due by `now_s`.
    pub fn flush(&mut self, now_s: f64) {
        while let Some((bytes, ())) = self.queue.pop_due(now_s) {
            // A failed write (no memory in the history, a shut-down participant) is a lost
            // sample, as a full socket buffer is on UDP.
            if self.writer.write(CdrBytes(bytes), None).is_ok() {
                self.stats.sent += 1;
            }
        }
    }

    /// The next sample waiting from a writer of the right type, if any (never blocks).
    pub fn recv(&mut self) -> Option<Vec<u8>> {
        while let Some(event) = self.status.try_recv_status() {
            if let DomainParticipantStatusEvent::WriterDetected { writer } = event {
                if writer.topic_name == self.in_topic {
                    self.writer_types
                        .insert(writer.guid, writer.type_name == self.in_type);
                }
            }
        }
        loop {
            match self.reader.take_next_sample() {
                Ok(Some(s)) => {
                    // A writer's discovery is reported before its samples can reach a reader.
                    if self.writer_types.get(&s.sample_info().writer_guid()) != Some(&true) {
                        self.stats.wrong_type += 1;
                        continue;
                    }
                    self.stats.received += 1;
                    return Some(s.into_value().0);
                }
                Ok(None) => return None,
                Err(_) => {
                    self.read_errors += 1;
                    return None;
                }
            }
        }
    }
}
