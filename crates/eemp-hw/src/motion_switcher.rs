//! The Go2's `motion_switcher` service: before the robot takes low-level commands its sport
//! mode must let go of the motors (`go2-dds-notes.md` §1.7). unitree_sdk2's RPC is a pair of
//! DDS topics, `rt/api/motion_switcher/request` (`unitree_api::msg::dds_::Request_`) and
//! `…/response` (`Response_`); a response carries the request's id and api id, a status code
//! (0: done) and a JSON string.
//!
//! [`release`] does what `go2_stand_example` does: CheckMode; while a mode holds the motors
//! (`name` non-empty: "normal" is sport_mode, "ai" ai_sport, …), ReleaseMode and ask again;
//! until released or the timeout, then an error that says what the robot last answered.
//! The loop itself ([`release_with`]) runs on any [`ModeService`], so it is tested without a
//! robot; [`ModeServer`] is the robot's side, for `eemp sim-robot --link dds`.

use crate::dds::{raw_reader, raw_writer, writer_qos, CdrBytes, DdsConfig, RawCdr};
use rustdds::no_key::{DataReader, DataWriter};
use rustdds::DomainParticipant;
use std::time::{Duration, Instant};

pub const SERVICE: &str = "motion_switcher";
pub const REQUEST_TOPIC: &str = "rt/api/motion_switcher/request";
pub const RESPONSE_TOPIC: &str = "rt/api/motion_switcher/response";
pub const REQUEST_TYPE_NAME: &str = "unitree_api::msg::dds_::Request_";
pub const RESPONSE_TYPE_NAME: &str = "unitree_api::msg::dds_::Response_";

/// The service's calls (`motion_switcher_api.py`, api version "1.0.0.1").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Api {
    CheckMode,
    SelectMode,
    ReleaseMode,
}

impl Api {
    pub fn id(self) -> i64 {
        match self {
            Api::CheckMode => 1001,
            Api::SelectMode => 1002,
            Api::ReleaseMode => 1003,
        }
    }

    pub fn from_id(id: i64) -> Option<Api> {
        [Api::CheckMode, Api::SelectMode, Api::ReleaseMode]
            .into_iter()
            .find(|a| a.id() == id)
    }
}

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RpcError {
    #[error("{0}: the message ends at byte {1}, a field needs more")]
    Short(&'static str, usize),
    #[error("{0}: encapsulation {1:02x?} is not plain CDR little endian (00 01 or 00 07)")]
    Encapsulation(&'static str, Vec<u8>),
    #[error("{0}: a string is not NUL-terminated UTF-8")]
    BadString(&'static str),
}

/// `unitree_api::msg::dds_::Request_` (header: identity, lease, policy; JSON parameter; binary).
#[derive(Clone, Debug, PartialEq)]
pub struct Request {
    /// Unique per call (the SDK uses a monotonic ns clock); the response repeats it.
    pub id: i64,
    pub api_id: i64,
    pub lease_id: i64,
    pub priority: i32,
    pub noreply: bool,
    pub parameter: String,
    pub binary: Vec<u8>,
}

/// `unitree_api::msg::dds_::Response_` (header: identity, status; JSON data; binary).
#[derive(Clone, Debug, PartialEq)]
pub struct Response {
    pub id: i64,
    pub api_id: i64,
    /// 0: done.
    pub code: i32,
    pub data: String,
    pub binary: Vec<u8>,
}

/// XCDR1 writer for the RPC types. Their 8-byte members all sit at 8-byte offsets, so XCDR2
/// (which aligns them to 4) gives the same bytes.
struct Out(Vec<u8>);

impl Out {
    fn new() -> Self {
        Out(vec![0x00, 0x01, 0x00, 0x00])
    }
    /// Alignment counts from the body, after the 4-byte encapsulation header.
    fn align(&mut self, n: usize) {
        while !(self.0.len() - 4).is_multiple_of(n) {
            self.0.push(0);
        }
    }
    fn i64(&mut self, v: i64) {
        self.align(8);
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn i32(&mut self, v: i32) {
        self.align(4);
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn bool(&mut self, v: bool) {
        self.0.push(v as u8);
    }
    /// A CDR string: length with the NUL, the bytes, the NUL.
    fn string(&mut self, s: &str) {
        self.i32(s.len() as i32 + 1);
        self.0.extend_from_slice(s.as_bytes());
        self.0.push(0);
    }
    fn bytes(&mut self, b: &[u8]) {
        self.i32(b.len() as i32);
        self.0.extend_from_slice(b);
    }
}

struct In<'a> {
    buf: &'a [u8],
    at: usize,
    what: &'static str,
}

impl<'a> In<'a> {
    fn new(buf: &'a [u8], what: &'static str) -> Result<Self, RpcError> {
        match buf.get(..2) {
            Some([0x00, 0x01]) | Some([0x00, 0x07]) => Ok(In { buf, at: 4, what }),
            _ => Err(RpcError::Encapsulation(
                what,
                buf.iter().take(4).copied().collect(),
            )),
        }
    }
    fn take(&mut self, n: usize, align: usize) -> Result<&'a [u8], RpcError> {
        self.at = 4 + (self.at - 4).div_ceil(align) * align;
        let end = self
            .at
            .checked_add(n)
            .ok_or(RpcError::Short(self.what, self.buf.len()))?;
        let got = self
            .buf
            .get(self.at..end)
            .ok_or(RpcError::Short(self.what, self.buf.len()))?;
        self.at = end;
        Ok(got)
    }
    fn i64(&mut self) -> Result<i64, RpcError> {
        Ok(i64::from_le_bytes(
            self.take(8, 8)?.try_into().expect("8 bytes"),
        ))
    }
    fn i32(&mut self) -> Result<i32, RpcError> {
        Ok(i32::from_le_bytes(
            self.take(4, 4)?.try_into().expect("4 bytes"),
        ))
    }
    fn bool(&mut self) -> Result<bool, RpcError> {
        Ok(self.take(1, 1)?[0] != 0)
    }
    fn len(&mut self) -> Result<usize, RpcError> {
        usize::try_from(self.i32()?).map_err(|_| RpcError::Short(self.what, self.buf.len()))
    }
    fn string(&mut self) -> Result<String, RpcError> {
        let n = self.len()?;
        let b = self.take(n, 1)?;
        match b.split_last() {
            Some((0, s)) => {
                String::from_utf8(s.to_vec()).map_err(|_| RpcError::BadString(self.what))
            }
            _ => Err(RpcError::BadString(self.what)),
        }
    }
    fn bytes(&mut self) -> Result<Vec<u8>, RpcError> {
        let n = self.len()?;
        Ok(self.take(n, 1)?.to_vec())
    }
}

impl Request {
    /// A call of `api` with an empty JSON object, as `MotionSwitcherClient` sends.
    pub fn call(api: Api, id: i64) -> Self {
        Request {
            id,
            api_id: api.id(),
            lease_id: 0,
            priority: 0,
            noreply: false,
            parameter: "{}".into(),
            binary: Vec::new(),
        }
    }

    /// CDR bytes, encapsulation header included.
    pub fn to_cdr(&self) -> Vec<u8> {
        let mut w = Out::new();
        w.i64(self.id);
        w.i64(self.api_id);
        w.i64(self.lease_id);
        w.i32(self.priority);
        w.bool(self.noreply);
        w.string(&self.parameter);
        w.bytes(&self.binary);
        w.0
    }

    pub fn from_cdr(bytes: &[u8]) -> Result<Self, RpcError> {
        let mut r = In::new(bytes, "Request_")?;
        Ok(Request {
            id: r.i64()?,
            api_id: r.i64()?,
            lease_id: r.i64()?,
            priority: r.i32()?,
            noreply: r.bool()?,
            parameter: r.string()?,
            binary: r.bytes()?,
        })
    }
}

impl Response {
    pub fn to_cdr(&self) -> Vec<u8> {
        let mut w = Out::new();
        w.i64(self.id);
        w.i64(self.api_id);
        w.i32(self.code);
        w.string(&self.data);
        w.bytes(&self.binary);
        w.0
    }

    pub fn from_cdr(bytes: &[u8]) -> Result<Self, RpcError> {
        let mut r = In::new(bytes, "Response_")?;
        Ok(Response {
            id: r.i64()?,
            api_id: r.i64()?,
            code: r.i32()?,
            data: r.string()?,
            binary: r.bytes()?,
        })
    }
}

/// The mode that holds the motors, from CheckMode's JSON (`{"form":"0","name":"normal"}`):
/// an empty `name` means released.
pub fn parse_check_mode(data: &str) -> Result<String, String> {
    let v: serde_json::Value = serde_json::from_str(data)
        .map_err(|e| format!("CheckMode answered '{data}', not JSON: {e}"))?;
    v.get("name")
        .and_then(|n| n.as_str())
        .map(str::to_owned)
        .ok_or_else(|| format!("CheckMode answered '{data}', without a string 'name'"))
}

/// What a call can come back with.
#[derive(Clone, Debug, PartialEq)]
pub enum CallError {
    /// No response within the call's timeout.
    NoAnswer,
    /// The service answered with a non-zero status code.
    Status(i32),
}

/// Something that answers motion-switcher calls: the robot over DDS, or a test's fake.
pub trait ModeService {
    /// Calls `api`; the response's data, or why not, within `timeout`.
    fn call(&mut self, api: Api, timeout: Duration) -> Result<String, CallError>;
    /// Where the service is, for messages.
    fn describe(&self) -> String;
}

/// How hard [`release`] tries.
#[derive(Clone, Debug, PartialEq)]
pub struct ReleaseOptions {
    /// Give up after this long, s.
    pub timeout_s: f64,
    /// Wait for one answer this long, s (unitree_sdk2_python's clients use 5 s).
    pub call_timeout_s: f64,
    /// Between a ReleaseMode and the next CheckMode, s (the Python example's 1 s; the C++
    /// one waits 5 s).
    pub retry_period_s: f64,
}

impl Default for ReleaseOptions {
    fn default() -> Self {
        ReleaseOptions {
            timeout_s: 20.0,
            call_timeout_s: 5.0,
            retry_period_s: 1.0,
        }
    }
}

impl ReleaseOptions {
    pub fn validate(&self) -> Result<(), String> {
        for (name, v) in [
            ("timeout_s", self.timeout_s),
            ("call_timeout_s", self.call_timeout_s),
            ("retry_period_s", self.retry_period_s),
        ] {
            if !(v.is_finite() && v > 0.0 && v <= 600.0) {
                return Err(format!(
                    "motion switcher {name} = {v} is out of range: allowed (0, 600] s"
                ));
            }
        }
        Ok(())
    }
}

const NO_RELEASE_HINT: &str =
    "for a robot already in low-level mode pass --no-release; otherwise turn sport mode off in \
     Unitree's app";

/// Releases whatever mode holds the motors; Ok with what was released ("" if nothing was).
pub fn release_with(
    service: &mut dyn ModeService,
    opts: &ReleaseOptions,
) -> Result<String, String> {
    opts.validate()?;
    let t0 = Instant::now();
    let deadline = Duration::from_secs_f64(opts.timeout_s);
    let call_timeout = Duration::from_secs_f64(opts.call_timeout_s);
    let mut first_mode: Option<String> = None;
    let mut last = String::from("no answer");
    loop {
        let left = deadline.saturating_sub(t0.elapsed());
        if left.is_zero() {
            return Err(format!(
                "could not release the Go2's motion control within {} s ({}): last: {last}; {NO_RELEASE_HINT}",
                opts.timeout_s,
                service.describe()
            ));
        }
        match service.call(Api::CheckMode, call_timeout.min(left)) {
            Ok(data) => {
                let name = parse_check_mode(&data)?;
                if name.is_empty() {
                    return Ok(first_mode.unwrap_or_default());
                }
                first_mode.get_or_insert_with(|| name.clone());
                last = format!("CheckMode says mode '{name}' holds the motors");
                match service.call(Api::ReleaseMode, call_timeout.min(left)) {
                    Ok(_) => {}
                    Err(CallError::Status(c)) => {
                        last += &format!(", ReleaseMode answered code {c}")
                    }
                    Err(CallError::NoAnswer) => last += ", ReleaseMode got no answer",
                }
                std::thread::sleep(
                    Duration::from_secs_f64(opts.retry_period_s)
                        .min(deadline.saturating_sub(t0.elapsed())),
                );
            }
            Err(CallError::Status(c)) => last = format!("CheckMode answered code {c}"),
            Err(CallError::NoAnswer) => {
                last = format!(
                    "no answer to CheckMode within {} s",
                    call_timeout.min(left).as_secs_f64()
                );
            }
        }
    }
}

/// The service on the robot, over DDS.
pub struct DdsModeService {
    writer: DataWriter<CdrBytes, RawCdr>,
    reader: DataReader<CdrBytes, RawCdr>,
    where_: String,
    next_id: i64,
    _participant: DomainParticipant,
}

impl DdsModeService {
    pub fn new(cfg: &DdsConfig) -> Result<Self, String> {
        let participant = cfg.participant()?;
        let writer = raw_writer(&participant, REQUEST_TOPIC, REQUEST_TYPE_NAME)?;
        // Reliable: a lost answer would cost a whole call timeout.
        let reader = raw_reader(
            &participant,
            RESPONSE_TOPIC,
            RESPONSE_TYPE_NAME,
            writer_qos(),
        )?;
        // Unique across runs, as the SDK's monotonic-ns ids are: a stale response of an
        // earlier run cannot be taken for this one's.
        let next_id = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos() as i64)
            .unwrap_or(1);
        Ok(DdsModeService {
            writer,
            reader,
            where_: format!(
                "service '{SERVICE}' on DDS domain {}{}",
                cfg.domain_id,
                cfg.iface
                    .as_ref()
                    .map(|i| format!(", interface {i}"))
                    .unwrap_or_default()
            ),
            next_id,
            _participant: participant,
        })
    }
}

impl ModeService for DdsModeService {
    fn call(&mut self, api: Api, timeout: Duration) -> Result<String, CallError> {
        self.next_id += 1;
        let req = Request::call(api, self.next_id);
        let bytes = CdrBytes(req.to_cdr());
        let t0 = Instant::now();
        let mut last_write: Option<Instant> = None;
        while t0.elapsed() < timeout {
            // Re-sent every 0.5 s: a request written before discovery matched the service's
            // reader is lost (volatile durability), and CheckMode / ReleaseMode are idempotent.
            if last_write.is_none_or(|t| t.elapsed() > Duration::from_millis(500)) {
                let _ = self.writer.write(bytes.clone(), None);
                last_write = Some(Instant::now());
            }
            while let Ok(Some(s)) = self.reader.take_next_sample() {
                // Another client's answers, or garbage, are not ours: skipped.
                let Ok(r) = Response::from_cdr(&s.into_value().0) else {
                    continue;
                };
                if r.id != req.id || r.api_id != req.api_id {
                    continue;
                }
                return if r.code == 0 {
                    Ok(r.data)
                } else {
                    Err(CallError::Status(r.code))
                };
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        Err(CallError::NoAnswer)
    }

    fn describe(&self) -> String {
        self.where_.clone()
    }
}

/// Releases the robot's mode over DDS (see [`release_with`]).
pub fn release(cfg: &DdsConfig, opts: &ReleaseOptions) -> Result<String, String> {
    release_with(&mut DdsModeService::new(cfg)?, opts)
}

/// The robot's side of the service, for the simulated Go2: it starts in `initial` mode
/// ("normal", sport mode, as a Go2 switched on; "" already released) and answers
/// CheckMode, ReleaseMode and SelectMode.
pub struct ModeServer {
    writer: DataWriter<CdrBytes, RawCdr>,
    reader: DataReader<CdrBytes, RawCdr>,
    pub mode: String,
    /// Requests that did not decode (counted, not answered).
    pub bad_requests: usize,
}

impl ModeServer {
    pub fn new(participant: &DomainParticipant, initial: &str) -> Result<Self, String> {
        Ok(ModeServer {
            writer: raw_writer(participant, RESPONSE_TOPIC, RESPONSE_TYPE_NAME)?,
            reader: raw_reader(participant, REQUEST_TOPIC, REQUEST_TYPE_NAME, writer_qos())?,
            mode: initial.into(),
            bad_requests: 0,
        })
    }

    /// The answer to one request (no DDS: the service's logic).
    pub fn answer(mode: &mut String, req: &Request) -> Response {
        let (code, data) = match Api::from_id(req.api_id) {
            Some(Api::CheckMode) => (
                0,
                serde_json::json!({"form": "0", "name": mode.as_str()}).to_string(),
            ),
            Some(Api::ReleaseMode) => {
                mode.clear();
                (0, String::new())
            }
            Some(Api::SelectMode) => {
                match serde_json::from_str::<serde_json::Value>(&req.parameter)
                    .ok()
                    .and_then(|v| v.get("name")?.as_str().map(str::to_owned))
                {
                    Some(name) => {
                        *mode = name;
                        (0, String::new())
                    }
                    // unitree_sdk2's RPC_ERR_SERVER_API_PARAMETER.
                    None => (3202, String::new()),
                }
            }
            // RPC_ERR_SERVER_API_NOT_IMPL.
            None => (3203, String::new()),
        };
        Response {
            id: req.id,
            api_id: req.api_id,
            code,
            data,
            binary: Vec::new(),
        }
    }

    /// Answers the requests that arrived (never blocks).
    pub fn serve(&mut self) {
        while let Ok(Some(s)) = self.reader.take_next_sample() {
            match Request::from_cdr(&s.into_value().0) {
                Ok(req) => {
                    let resp = Self::answer(&mut self.mode, &req);
                    if !req.noreply {
                        let _ = self.writer.write(CdrBytes(resp.to_cdr()), None);
                    }
                }
                Err(_) => self.bad_requests += 1,
            }
        }
    }

    /// Whether low-level commands reach the motors (no mode holds them).
    pub fn released(&self) -> bool {
        self.mode.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_request_is_laid_out_as_xcdr1() {
        let r = Request::call(Api::ReleaseMode, 0x0102_0304_0506_0708);
        let b = r.to_cdr();
        // Header, id @0, api_id @8, lease @16, priority @24, noreply @28, then the parameter
        // string (length with its NUL) 4-aligned @32, then the empty binary sequence.
        let mut want = vec![0x00, 0x01, 0x00, 0x00];
        want.extend_from_slice(&0x0102_0304_0506_0708i64.to_le_bytes());
        want.extend_from_slice(&1003i64.to_le_bytes());
        want.extend_from_slice(&0i64.to_le_bytes());
        want.extend_from_slice(&0i32.to_le_bytes());
        want.extend_from_slice(&[0, 0, 0, 0]);
        want.extend_from_slice(&3i32.to_le_bytes());
        want.extend_from_slice(b"{}\0");
        want.push(0);
        want.extend_from_slice(&0i32.to_le_bytes());
        assert_eq!(b, want);
        assert_eq!(Request::from_cdr(&b).unwrap(), r);
    }

    #[test]
    fn a_response_round_trips_and_bad_bytes_are_errors() {
        let r = Response {
            id: -5,
            api_id: 1001,
            code: 0,
            data: r#"{"form":"0","name":"normal"}"#.into(),
            binary: vec![1, 2, 3],
        };
        let b = r.to_cdr();
        assert_eq!(Response::from_cdr(&b).unwrap(), r);
        assert_eq!(parse_check_mode(&r.data).unwrap(), "normal");
        assert_eq!(parse_check_mode(r#"{"form":"0","name":""}"#).unwrap(), "");
        assert!(parse_check_mode("{}").unwrap_err().contains("'name'"));
        assert!(parse_check_mode("nope").unwrap_err().contains("not JSON"));
        for cut in 0..b.len() {
            assert!(Response::from_cdr(&b[..cut]).is_err(), "cut at {cut}");
        }
        let mut huge = b.clone();
        huge[4 + 20..4 + 24].copy_from_slice(&i32::MAX.to_le_bytes());
        assert!(Response::from_cdr(&huge).is_err());
        let mut be = b.clone();
        be[1] = 0x00;
        assert!(matches!(
            Response::from_cdr(&be),
            Err(RpcError::Encapsulation(..))
        ));
    }

    /// A robot that needs `releases` ReleaseModes (or never answers).
    struct Fake {
        mode: String,
        releases_needed: usize,
        silent: bool,
        calls: Vec<Api>,
    }

    impl ModeService for Fake {
        fn call(&mut self, api: Api, timeout: Duration) -> Result<String, CallError> {
            self.calls.push(api);
            if self.silent {
                std::thread::sleep(timeout);
                return Err(CallError::NoAnswer);
            }
            if api == Api::ReleaseMode {
                if self.releases_needed <= 1 {
                    self.mode.clear();
                }
                self.releases_needed = self.releases_needed.saturating_sub(1);
            }
            let req = Request::call(api, 1);
            let resp = ModeServer::answer(&mut self.mode.clone(), &req);
            Ok(resp.data)
        }
        fn describe(&self) -> String {
            "the fake".into()
        }
    }

    fn quick() -> ReleaseOptions {
        ReleaseOptions {
            timeout_s: 0.3,
            call_timeout_s: 0.05,
            retry_period_s: 0.01,
        }
    }

    #[test]
    fn release_asks_until_the_mode_lets_go() {
        let mut f = Fake {
            mode: "normal".into(),
            releases_needed: 2,
            silent: false,
            calls: vec![],
        };
        assert_eq!(release_with(&mut f, &quick()).unwrap(), "normal");
        use Api::*;
        assert_eq!(
            f.calls,
            [CheckMode, ReleaseMode, CheckMode, ReleaseMode, CheckMode]
        );
        // Already released: one CheckMode, nothing to release.
        let mut f = Fake {
            mode: String::new(),
            releases_needed: 0,
            silent: false,
            calls: vec![],
        };
        assert_eq!(release_with(&mut f, &quick()).unwrap(), "");
        assert_eq!(f.calls, [CheckMode]);
    }

    #[test]
    fn release_gives_up_at_the_timeout_saying_why() {
        let mut f = Fake {
            mode: "ai".into(),
            releases_needed: usize::MAX,
            silent: false,
            calls: vec![],
        };
        let t0 = Instant::now();
        let e = release_with(&mut f, &quick()).unwrap_err();
        assert!(t0.elapsed() < Duration::from_secs(2));
        assert!(
            e.contains("within 0.3 s") && e.contains("mode 'ai'") && e.contains("--no-release"),
            "{e}"
        );
        let mut f = Fake {
            mode: "normal".into(),
            releases_needed: 0,
            silent: true,
            calls: vec![],
        };
        let e = release_with(&mut f, &quick()).unwrap_err();
        assert!(
            e.contains("no answer to CheckMode") && e.contains("the fake"),
            "{e}"
        );
        let bad = ReleaseOptions {
            timeout_s: -1.0,
            ..quick()
        };
        assert!(release_with(&mut f, &bad)
            .unwrap_err()
            .contains("timeout_s = -1"));
    }

    #[test]
    fn the_server_answers_as_the_robot() {
        let mut mode = String::from("normal");
        let r = ModeServer::answer(&mut mode, &Request::call(Api::CheckMode, 7));
        assert_eq!((r.id, r.api_id, r.code), (7, 1001, 0));
        assert_eq!(parse_check_mode(&r.data).unwrap(), "normal");
        ModeServer::answer(&mut mode, &Request::call(Api::ReleaseMode, 8));
        assert_eq!(mode, "");
        let mut odd = Request::call(Api::CheckMode, 9);
        odd.api_id = 4242;
        assert_eq!(ModeServer::answer(&mut mode, &odd).code, 3203);
    }
}
