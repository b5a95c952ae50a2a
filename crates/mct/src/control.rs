//! The transport-independent core: commands in, replies, state, events, exec_info and io out.
//!
//! [`ControlPlane::parse`] turns what arrived on `cetratus/<plc-id>/cmd/<verb>` into a typed
//! [`IncomingCommand`], or into a [`Rejection`] that already holds the error reply and the event.
//! Nothing here touches the network, so it is tested without a broker.

use std::time::Duration;

use base64::Engine as _;
use serde::{Deserialize, Serialize};
use serde_json::{json, Map, Value};

use crate::envelope::{Envelope, OperatorKeys};
use crate::MctError;

/// Largest command payload accepted (1 MiB): a package bigger than this belongs in a file.
pub const MAX_PAYLOAD: usize = 1 << 20;

/// The command verbs, as the last topic level under `cmd/`.
pub const VERBS: [&str; 6] = [
    "load",
    "remove",
    "substitute",
    "abort",
    "reset",
    "exec_info",
];

/// Why a command failed: the `error.code` of a reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ErrorCode {
    /// Not JSON, not an object, a field of the wrong type, an unknown field, bad base64.
    Malformed,
    /// The payload is larger than [`MAX_PAYLOAD`].
    TooLarge,
    /// The topic names no known verb.
    UnknownVerb,
    /// Operator keys are configured and the command is unsigned or its signature is bad.
    Unauthorised,
    /// A signed command's nonce was already used inside the replay window.
    Replayed,
    /// The command asked for something only local configuration may grant (`allow_unsigned`).
    NotAllowed,
    /// The scan thread's command queue is full; retry.
    Busy,
    /// The PLC refused the command (wrong state, bad package, ...); the message says why.
    Refused,
    /// The PLC did not answer (it is shutting down).
    Unavailable,
}

impl ErrorCode {
    /// The snake_case name used in payloads.
    pub fn name(self) -> &'static str {
        match self {
            ErrorCode::Malformed => "malformed",
            ErrorCode::TooLarge => "too_large",
            ErrorCode::UnknownVerb => "unknown_verb",
            ErrorCode::Unauthorised => "unauthorised",
            ErrorCode::Replayed => "replayed",
            ErrorCode::NotAllowed => "not_allowed",
            ErrorCode::Busy => "busy",
            ErrorCode::Refused => "refused",
            ErrorCode::Unavailable => "unavailable",
        }
    }
}

/// Where and how a reply goes: the MQTT 5 response topic and correlation data, or the MQTT 3.1.1
/// `reply_to` and `correlation` fields of the payload.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReplyHandle {
    /// The verb the reply answers.
    pub verb: String,
    /// Topic to publish the reply on; `None` when the sender asked for no reply.
    pub topic: Option<String>,
    /// MQTT 5 correlation data, echoed as a property.
    pub correlation_data: Option<Vec<u8>>,
    /// The payload's `correlation` field, echoed in the reply body.
    pub correlation: Option<Value>,
    /// A number unique per command since start, for the audit log.
    pub request_id: u64,
}

/// The `error` object of a failed reply.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ErrorBody {
    /// Machine-readable reason.
    pub code: ErrorCode,
    /// What was wrong and what to do.
    pub message: String,
}

/// A reply: `ok`, and either `result` or `error`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Reply {
    /// Whether the command was accepted.
    pub ok: bool,
    /// What the command produced (for `exec_info`, the figures), on success.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub result: Option<Value>,
    /// Why it failed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<ErrorBody>,
}

impl Reply {
    /// Success with a result (use `Value::Null` for none).
    pub fn ok(result: Value) -> Self {
        Reply {
            ok: true,
            result: (!result.is_null()).then_some(result),
            error: None,
        }
    }
    /// Failure.
    pub fn err(code: ErrorCode, message: impl Into<String>) -> Self {
        Reply {
            ok: false,
            result: None,
            error: Some(ErrorBody {
                code,
                message: message.into(),
            }),
        }
    }
    /// The PLC refused the command: `Plc::command`'s error message becomes a `refused` reply.
    pub fn from_result(r: Result<Value, String>) -> Self {
        match r {
            Ok(v) => Reply::ok(v),
            Err(m) => Reply::err(ErrorCode::Refused, m),
        }
    }
}

/// Arguments of `substitute`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SubstituteArgs {
    /// `retransform` (default) or `keep`.
    #[serde(default)]
    pub mode: Option<String>,
    /// Wait until this predicate over the primary marking holds (guard syntax).
    #[serde(default)]
    pub when: Option<String>,
    /// Give up waiting after this many milliseconds.
    #[serde(default)]
    pub within_ms: Option<u64>,
    /// `keep` even with drift.
    #[serde(default)]
    pub force: bool,
}

/// A command, parsed and authorised.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Request {
    /// Load an update package (its bytes, base64-decoded here so the scan side never parses).
    Load {
        /// The package file's bytes.
        package: Vec<u8>,
    },
    /// Drop the candidate in quarantine.
    Remove,
    /// Make the candidate PRIMARY.
    Substitute(SubstituteArgs),
    /// Cancel the update under way.
    Abort,
    /// Leave the fault state.
    Reset,
    /// Reply with both containers' `program_exec_info`.
    ExecInfo,
}

impl Request {
    /// The verb.
    pub fn verb(&self) -> &'static str {
        match self {
            Request::Load { .. } => "load",
            Request::Remove => "remove",
            Request::Substitute(_) => "substitute",
            Request::Abort => "abort",
            Request::Reset => "reset",
            Request::ExecInfo => "exec_info",
        }
    }
}

/// A command for the scan side, with the handle to answer it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct IncomingCommand {
    /// What is asked.
    pub request: Request,
    /// Where the answer goes; pass it back in [`crate::Outgoing::Reply`].
    pub reply: ReplyHandle,
    /// The operator key that signed it, for the audit log (`None` when keys are not configured).
    pub key_id: Option<String>,
}

/// A command turned down before reaching the PLC: the reply (if the sender said where) and the
/// event for `events`.
#[derive(Clone, Debug, PartialEq)]
pub struct Rejection {
    /// The error reply and where it goes; `None` when the sender gave no reply address.
    pub reply: Option<(ReplyHandle, Reply)>,
    /// A `command_rejected` event.
    pub event: Value,
}

/// A program's identity in `state`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProgramInfo {
    /// Name.
    pub name: String,
    /// Version.
    pub version: String,
    /// Hex SHA-256.
    pub hash: String,
}

/// The programs in A and B.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Programs {
    /// Container A (`null` when empty).
    #[serde(rename = "A")]
    pub a: Option<ProgramInfo>,
    /// Container B (`null` when empty).
    #[serde(rename = "B")]
    pub b: Option<ProgramInfo>,
}

/// The retained `state` message.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StateMsg {
    /// Always true here; the last will publishes `{"online": false}`.
    pub online: bool,
    /// PRIMARY: "A" or "B".
    pub primary: String,
    /// STATUS: "idle", "setup", "quarantine" or "fault".
    pub status: String,
    /// Programs in A and B.
    pub programs: Programs,
    /// Cycle figures (cycles, scan/cycle time summaries, overruns), as the runtime reports them.
    pub cycle: Value,
}

/// The control plane of one PLC: topic names, command parsing, payload formatting.
#[derive(Debug)]
pub struct ControlPlane {
    prefix: String,
    keys: Option<OperatorKeys>,
    next_id: u64,
}

fn valid_topic(t: &str) -> bool {
    !t.is_empty() && t.len() <= 1024 && !t.contains(['+', '#', '\0'])
}

fn rejected_event(verb: &str, code: ErrorCode, message: &str, request_id: u64) -> Value {
    json!({
        "kind": "command_rejected",
        "message": format!("{verb}: {message}"),
        "detail": {"verb": verb, "code": code, "request_id": request_id},
    })
}

impl ControlPlane {
    /// The control plane of PLC `plc_id`; with operator keys, every command must be signed.
    pub fn new(plc_id: &str, keys: Option<OperatorKeys>) -> Result<Self, MctError> {
        if plc_id.is_empty()
            || plc_id.contains(['/', '+', '#'])
            || plc_id.chars().any(char::is_control)
        {
            return Err(MctError::PlcId(plc_id.to_string()));
        }
        Ok(ControlPlane {
            prefix: format!("cetratus/{plc_id}/"),
            keys: keys.filter(|k| !k.is_empty()),
            next_id: 1,
        })
    }

    /// The full topic of a leaf such as `state` or `events`.
    pub fn topic(&self, leaf: &str) -> String {
        format!("{}{leaf}", self.prefix)
    }

    /// The subscription that receives every command.
    pub fn command_filter(&self) -> String {
        self.topic("cmd/+")
    }

    /// Whether commands must be signed.
    pub fn requires_signature(&self) -> bool {
        self.keys.is_some()
    }

    /// Parses, validates and authorises one command. `now_unix_s` is the wall clock for the replay
    /// window (passed in so tests are deterministic).
    pub fn parse(
        &mut self,
        topic: &str,
        payload: &[u8],
        response_topic: Option<&str>,
        correlation_data: Option<&[u8]>,
        now_unix_s: u64,
    ) -> Result<IncomingCommand, Box<Rejection>> {
        let request_id = self.next_id;
        self.next_id += 1;
        let verb_raw = topic
            .strip_prefix(&self.prefix)
            .and_then(|r| r.strip_prefix("cmd/"))
            .unwrap_or(topic);
        let verb = VERBS.iter().find(|v| **v == verb_raw).copied();
        // The reply address is read before anything else can fail, so every failure is answered.
        let parsed: Result<Value, String> = if payload.is_empty() {
            Ok(Value::Object(Map::new()))
        } else {
            serde_json::from_slice(payload).map_err(|e| e.to_string())
        };
        let obj = parsed.as_ref().ok().and_then(Value::as_object);
        let reply_to = response_topic
            .map(str::to_string)
            .or_else(|| {
                obj.and_then(|o| o.get("reply_to"))
                    .and_then(Value::as_str)
                    .map(str::to_string)
            })
            .filter(|t| valid_topic(t));
        let handle = ReplyHandle {
            verb: verb.unwrap_or(verb_raw).chars().take(64).collect(),
            topic: reply_to,
            correlation_data: correlation_data.map(<[u8]>::to_vec),
            correlation: obj.and_then(|o| o.get("correlation")).cloned(),
            request_id,
        };
        let reject = |code: ErrorCode, message: String| {
            Box::new(Rejection {
                event: rejected_event(&handle.verb, code, &message, request_id),
                reply: handle
                    .topic
                    .is_some()
                    .then(|| (handle.clone(), Reply::err(code, message))),
            })
        };
        let Some(verb) = verb else {
            return Err(reject(
                ErrorCode::UnknownVerb,
                format!(
                    "unknown verb `{}`; expected one of {}",
                    handle.verb,
                    VERBS.join(", ")
                ),
            ));
        };
        if payload.len() > MAX_PAYLOAD {
            return Err(reject(
                ErrorCode::TooLarge,
                format!(
                    "payload of {} bytes exceeds the limit of {MAX_PAYLOAD} bytes",
                    payload.len()
                ),
            ));
        }
        let obj = match (&parsed, obj) {
            (Err(e), _) => {
                return Err(reject(
                    ErrorCode::Malformed,
                    format!("payload is not JSON: {e}"),
                ))
            }
            (Ok(_), None) => {
                return Err(reject(
                    ErrorCode::Malformed,
                    "payload must be a JSON object".into(),
                ))
            }
            (Ok(_), Some(o)) => o.clone(),
        };
        let (mut body, key_id) = match self.keys.as_mut() {
            None => (obj, None),
            Some(keys) => {
                let Some(env) = obj.get("envelope") else {
                    return Err(reject(
                        ErrorCode::Unauthorised,
                        "operator keys are configured: the command must be a signed envelope"
                            .into(),
                    ));
                };
                let env: Envelope = serde_json::from_value(env.clone())
                    .map_err(|e| reject(ErrorCode::Malformed, format!("bad envelope: {e}")))?;
                let (inner, key_id) = keys
                    .verify(verb, &env, now_unix_s)
                    .map_err(|(code, m)| reject(code, m))?;
                let inner: Value = serde_json::from_slice(&inner).map_err(|e| {
                    reject(
                        ErrorCode::Malformed,
                        format!("signed payload is not JSON: {e}"),
                    )
                })?;
                match inner {
                    Value::Object(o) => (o, Some(key_id)),
                    _ => {
                        return Err(reject(
                            ErrorCode::Malformed,
                            "signed payload must be a JSON object".into(),
                        ))
                    }
                }
            }
        };
        if body.contains_key("allow_unsigned") {
            return Err(reject(
                ErrorCode::NotAllowed,
                "allow_unsigned is a local configuration setting and is never accepted from a command".into(),
            ));
        }
        for meta in ["reply_to", "correlation", "envelope"] {
            body.remove(meta);
        }
        let request = Self::request(verb, body).map_err(|m| reject(ErrorCode::Malformed, m))?;
        Ok(IncomingCommand {
            request,
            reply: handle,
            key_id,
        })
    }

    fn request(verb: &str, body: Map<String, Value>) -> Result<Request, String> {
        let no_args = |r: Request| {
            if let Some(k) = body.keys().next() {
                Err(format!("`{verb}` takes no arguments; unknown field `{k}`"))
            } else {
                Ok(r)
            }
        };
        match verb {
            "load" => {
                #[derive(Deserialize)]
                #[serde(deny_unknown_fields)]
                struct Load {
                    package_b64: String,
                }
                let l: Load = serde_json::from_value(Value::Object(body))
                    .map_err(|e| format!("bad `load` arguments: {e}"))?;
                let package = base64::engine::general_purpose::STANDARD
                    .decode(l.package_b64.trim())
                    .map_err(|e| format!("package_b64 is not base64: {e}"))?;
                if package.is_empty() {
                    return Err("package_b64 is empty".into());
                }
                Ok(Request::Load { package })
            }
            "substitute" => {
                let a: SubstituteArgs = serde_json::from_value(Value::Object(body))
                    .map_err(|e| format!("bad `substitute` arguments: {e}"))?;
                if let Some(m) = &a.mode {
                    if m != "retransform" && m != "keep" {
                        return Err(format!(
                            "unknown substitution mode `{m}`; expected retransform or keep"
                        ));
                    }
                }
                Ok(Request::Substitute(a))
            }
            "remove" => no_args(Request::Remove),
            "abort" => no_args(Request::Abort),
            "reset" => no_args(Request::Reset),
            _ => no_args(Request::ExecInfo),
        }
    }

    /// The JSON body of a reply: `ok`, `verb`, `request_id`, `correlation` (if given), and
    /// `result` or `error`.
    pub fn reply_payload(handle: &ReplyHandle, reply: &Reply) -> Vec<u8> {
        let mut v = json!({"ok": reply.ok, "verb": handle.verb, "request_id": handle.request_id});
        if let Some(c) = &handle.correlation {
            v["correlation"] = c.clone();
        }
        if let Some(r) = &reply.result {
            v["result"] = r.clone();
        }
        if let Some(e) = &reply.error {
            v["error"] = json!({"code": e.code, "message": e.message});
        }
        v.to_string().into_bytes()
    }

    /// The audit event of an accepted command.
    pub fn accepted_event(cmd: &IncomingCommand) -> Value {
        json!({
            "kind": "command_received",
            "message": format!("{} received", cmd.reply.verb),
            "detail": {"verb": cmd.reply.verb, "request_id": cmd.reply.request_id, "key_id": cmd.key_id},
        })
    }

    /// The retained payload that says the PLC is gone (the last will, and a clean shutdown).
    pub fn offline_payload() -> Vec<u8> {
        br#"{"online":false}"#.to_vec()
    }
}

/// Seconds since the Unix epoch, for the replay window.
pub fn unix_now() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or(Duration::ZERO)
        .as_secs()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cp() -> ControlPlane {
        ControlPlane::new("cell1", None).expect("valid id")
    }

    fn code(r: Result<IncomingCommand, Box<Rejection>>) -> ErrorCode {
        match r {
            Ok(c) => panic!("accepted: {c:?}"),
            Err(rej) => rej.reply.expect("a reply").1.error.expect("an error").code,
        }
    }

    #[test]
    fn a_load_with_reply_to_parses_into_the_package_bytes() {
        let p = br#"{"package_b64":"aGVsbG8=","reply_to":"me/r","correlation":42}"#;
        let c = cp()
            .parse("cetratus/cell1/cmd/load", p, None, None, 0)
            .expect("accepted");
        assert_eq!(
            c.request,
            Request::Load {
                package: b"hello".to_vec()
            }
        );
        assert_eq!(c.reply.topic.as_deref(), Some("me/r"));
        assert_eq!(c.reply.correlation, Some(json!(42)));
    }

    #[test]
    fn the_mqtt5_response_topic_wins_over_reply_to() {
        let c = cp()
            .parse(
                "cetratus/cell1/cmd/abort",
                br#"{"reply_to":"x"}"#,
                Some("v5/r"),
                Some(b"c1"),
                0,
            )
            .expect("accepted");
        assert_eq!(c.reply.topic.as_deref(), Some("v5/r"));
        assert_eq!(c.reply.correlation_data.as_deref(), Some(&b"c1"[..]));
    }

    #[test]
    fn bad_commands_get_the_right_error_codes() {
        let r = Some("r");
        assert_eq!(
            code(cp().parse("cetratus/cell1/cmd/explode", b"{}", r, None, 0)),
            ErrorCode::UnknownVerb
        );
        assert_eq!(
            code(cp().parse("cetratus/cell1/cmd/load", b"\xff\x00", r, None, 0)),
            ErrorCode::Malformed
        );
        assert_eq!(
            code(cp().parse("cetratus/cell1/cmd/load", b"[1]", r, None, 0)),
            ErrorCode::Malformed
        );
        assert_eq!(
            code(cp().parse("cetratus/cell1/cmd/load", b"{}", r, None, 0)),
            ErrorCode::Malformed
        );
        assert_eq!(
            code(cp().parse(
                "cetratus/cell1/cmd/load",
                br#"{"package_b64":"!!"}"#,
                r,
                None,
                0
            )),
            ErrorCode::Malformed
        );
        assert_eq!(
            code(cp().parse("cetratus/cell1/cmd/remove", br#"{"x":1}"#, r, None, 0)),
            ErrorCode::Malformed
        );
        assert_eq!(
            code(cp().parse(
                "cetratus/cell1/cmd/substitute",
                br#"{"mode":"yolo"}"#,
                r,
                None,
                0
            )),
            ErrorCode::Malformed
        );
        let huge = vec![b' '; MAX_PAYLOAD + 1];
        assert_eq!(
            code(cp().parse("cetratus/cell1/cmd/load", &huge, r, None, 0)),
            ErrorCode::TooLarge
        );
    }

    #[test]
    fn allow_unsigned_from_a_command_is_never_accepted() {
        let p = br#"{"package_b64":"aGVsbG8=","allow_unsigned":true}"#;
        assert_eq!(
            code(cp().parse("cetratus/cell1/cmd/load", p, Some("r"), None, 0)),
            ErrorCode::NotAllowed
        );
    }

    #[test]
    fn a_rejection_without_reply_address_still_makes_an_event() {
        let rej = cp()
            .parse("cetratus/cell1/cmd/load", b"nope", None, None, 0)
            .expect_err("rejected");
        assert!(rej.reply.is_none());
        assert_eq!(rej.event["kind"], "command_rejected");
    }

    #[test]
    fn with_operator_keys_an_unsigned_command_is_unauthorised_and_a_signed_one_passes() {
        let sk = ed25519_dalek::SigningKey::from_bytes(&[5u8; 32]);
        let mut keys = OperatorKeys::new(Duration::from_secs(30));
        keys.add("op", sk.verifying_key());
        let mut cp = ControlPlane::new("cell1", Some(keys)).expect("valid id");
        assert_eq!(
            code(cp.parse("cetratus/cell1/cmd/abort", b"{}", Some("r"), None, 100)),
            ErrorCode::Unauthorised
        );
        let env = crate::envelope::sign("abort", b"{}", 100, "n-123456", "op", &sk);
        let payload = serde_json::to_vec(&json!({"envelope": env})).expect("serialisable");
        let c = cp
            .parse("cetratus/cell1/cmd/abort", &payload, Some("r"), None, 100)
            .expect("accepted");
        assert_eq!(c.key_id.as_deref(), Some("op"));
        assert_eq!(
            code(cp.parse("cetratus/cell1/cmd/abort", &payload, Some("r"), None, 100)),
            ErrorCode::Replayed
        );
    }

    #[test]
    fn a_plc_id_with_topic_wildcards_is_refused() {
        assert!(ControlPlane::new("a/b", None).is_err());
        assert!(ControlPlane::new("", None).is_err());
    }
}
