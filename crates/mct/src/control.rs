//! The transport-independent core: commands in, replies, state, events, exec_info and io out.
//!
//! [`ControlPlane::parse`] turns what arrived on `cetratus/<plc-id>/cmd/<verb>` into a typed
//! [`IncomingCommand`], or into a [`Rejection`] that already holds the error reply and the event.
//! Nothing here touches the network, so it is tested without a broker.

use std::time::Duration;

use base64::Engine as _;
use cetratus_proto::{
    command_from_body, Accepted, ErrorBody, ErrorCode, EventKind, EventMsg, PlcId, ProtoError,
    Reply, ReplyFields, SubstituteArgs, Topics, Verb, MAX_PAYLOAD,
};
use serde_json::{json, Map, Value};

use crate::envelope::{parse_envelope, OperatorKeys};
use crate::MctError;

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

/// What a command came to: its result (for `exec_info`, the figures), or why it failed.
pub type Outcome = Result<Option<Value>, ErrorBody>;

/// The outcome of a command the PLC refused: `Plc::command`'s error becomes a `refused` reply.
pub fn refused(message: impl Into<String>) -> ErrorBody {
    ErrorBody {
        code: ErrorCode::Refused,
        message: message.into(),
    }
}

/// The outcome of an accepted command: `{"accepted": true}`.
pub fn accepted() -> Outcome {
    let accepted = Accepted {
        accepted: true,
        verdicts: Vec::new(),
    };
    Ok(serde_json::to_value(accepted).ok())
}

/// A command, parsed and authorised: a load carries the package's bytes (base64-decoded here, so
/// the scan side never parses), a substitution its arguments.
pub type Request = cetratus_vocab::Command<Vec<u8>, SubstituteArgs>;

/// A command that passed the checks: what it asks, the operator key that signed it and the
/// account the signer acted for (both `None` without operator keys).
type Authorised = (Request, Option<String>, Option<String>);

/// A command for the scan side, with the handle to answer it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct IncomingCommand {
    /// What is asked.
    pub request: Request,
    /// Where the answer goes; pass it back in [`crate::Outgoing::Reply`].
    pub reply: ReplyHandle,
    /// The operator key that signed it, for the audit log (`None` when keys are not configured).
    pub key_id: Option<String>,
    /// The account the signer acted for, as the signed envelope names it (a dashboard login).
    pub account: Option<String>,
}

/// A command turned down before reaching the PLC: the reply (if the sender said where) and the
/// event for `events`.
#[derive(Clone, Debug, PartialEq)]
pub struct Rejection {
    /// The error reply and where it goes; `None` when the sender gave no reply address.
    pub reply: Option<(ReplyHandle, ErrorBody)>,
    /// A `command_rejected` event.
    pub event: EventMsg,
}

/// The control plane of one PLC: topic names, command parsing, payload formatting.
#[derive(Debug)]
pub struct ControlPlane {
    topics: Topics,
    keys: Option<OperatorKeys>,
    next_id: u64,
}

fn valid_topic(t: &str) -> bool {
    !t.is_empty() && t.len() <= 1024 && !t.contains(['+', '#', '\0'])
}

fn rejected_event(verb: &str, code: ErrorCode, message: &str, request_id: u64) -> EventMsg {
    EventMsg {
        cycle: None,
        time_us: None,
        kind: EventKind::CommandRejected.into(),
        message: format!("{verb}: {message}"),
        detail: json!({"verb": verb, "code": code, "request_id": request_id}),
    }
}

impl ControlPlane {
    /// The control plane of PLC `plc_id`; with operator keys, every command must be signed.
    pub fn new(plc_id: &str, keys: Option<OperatorKeys>) -> Result<Self, MctError> {
        let plc = PlcId::new(plc_id).map_err(|_| MctError::PlcId(plc_id.to_string()))?;
        Ok(ControlPlane {
            topics: Topics::new(plc),
            keys: keys.filter(|k| !k.is_empty()),
            next_id: 1,
        })
    }

    /// The topics of this PLC.
    pub fn topics(&self) -> &Topics {
        &self.topics
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
        let verb_raw = self
            .topics
            .strip(topic)
            .and_then(|r| r.strip_prefix("cmd/"))
            .unwrap_or(topic);
        let verb = verb_raw.parse::<Verb>().ok();
        // The reply address is read before anything else can fail, so every failure is answered.
        let parsed: Result<Value, String> = if payload.is_empty() {
            Ok(Value::Object(Map::new()))
        } else {
            serde_json::from_slice(payload).map_err(|e| e.to_string())
        };
        let obj = parsed.as_ref().ok().and_then(Value::as_object);
        let asked = response_topic.map(str::to_string).or_else(|| {
            obj.and_then(|o| o.get("reply_to"))
                .and_then(Value::as_str)
                .map(str::to_string)
        });
        // Replies go only under this PLC's own `reply/` level: a command cannot make the PLC
        // publish on another PLC's topics, or anywhere else.
        let reply_prefix = format!("{}reply/", self.topics.prefix());
        let foreign_reply = asked
            .as_ref()
            .filter(|t| !(t.starts_with(&reply_prefix) && t.len() > reply_prefix.len()))
            .map(|t| t.chars().take(128).collect::<String>());
        let handle = ReplyHandle {
            verb: verb
                .map_or(verb_raw, |v| v.as_str())
                .chars()
                .take(64)
                .collect(),
            topic: asked.filter(|t| valid_topic(t) && foreign_reply.is_none()),
            correlation_data: correlation_data.map(<[u8]>::to_vec),
            correlation: obj.and_then(|o| o.get("correlation")).cloned(),
            request_id,
        };
        let checked = match (foreign_reply, verb) {
            (Some(t), _) => Err((
                ErrorCode::NotAllowed,
                format!(
                    "the reply topic `{t}` is not under `{reply_prefix}`; this PLC replies only \
                     there: ask for a reply on `{reply_prefix}<your client>`"
                ),
            )),
            (None, None) => Err((
                ErrorCode::UnknownVerb,
                format!(
                    "unknown verb `{}`; expected one of {}",
                    handle.verb,
                    Verb::ALL
                        .iter()
                        .map(|v| v.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )),
            (None, Some(verb)) => self.authorise(verb, payload.len(), &parsed, &handle, now_unix_s),
        };
        match checked {
            Ok((request, key_id, account)) => Ok(IncomingCommand {
                request,
                reply: handle,
                key_id,
                account,
            }),
            Err((code, message)) => Err(Box::new(Rejection {
                event: rejected_event(&handle.verb, code, &message, request_id),
                reply: handle
                    .topic
                    .is_some()
                    .then_some((handle, ErrorBody { code, message })),
            })),
        }
    }

    /// The checks of a command with a known verb and an allowed reply address: its size, its
    /// JSON, its signature when keys are configured, and its arguments.
    fn authorise(
        &mut self,
        verb: Verb,
        bytes: usize,
        parsed: &Result<Value, String>,
        handle: &ReplyHandle,
        now_unix_s: u64,
    ) -> Result<Authorised, (ErrorCode, String)> {
        if bytes > MAX_PAYLOAD {
            return Err((
                ErrorCode::TooLarge,
                format!("payload of {bytes} bytes exceeds the limit of {MAX_PAYLOAD} bytes"),
            ));
        }
        let obj = match parsed {
            Err(e) => return Err((ErrorCode::Malformed, format!("payload is not JSON: {e}"))),
            Ok(Value::Object(o)) => o.clone(),
            Ok(_) => return Err((ErrorCode::Malformed, "payload must be a JSON object".into())),
        };
        let (mut body, key_id, account) = match self.keys.as_mut() {
            None => (obj, None, None),
            Some(keys) => {
                let plc = self.topics.plc().as_str();
                let u = unseal(keys, plc, verb, &obj, handle, now_unix_s)?;
                (u.body, Some(u.key_id), u.account)
            }
        };
        if body.contains_key("allow_unsigned") {
            return Err((
                ErrorCode::NotAllowed,
                "allow_unsigned is a local configuration setting and is never accepted from a command".into(),
            ));
        }
        for meta in ReplyFields::META_FIELDS {
            body.remove(meta);
        }
        let request = Self::request(verb, body).map_err(|m| (ErrorCode::Malformed, m))?;
        Ok((request, key_id, account))
    }

    fn request(verb: Verb, body: Map<String, Value>) -> Result<Request, String> {
        let command = command_from_body(verb, Value::Object(body)).map_err(|e| match e {
            ProtoError::Payload { source, .. } if !verb.takes_arguments() => {
                format!("`{verb}` takes no arguments: {source}")
            }
            ProtoError::Payload { source, .. } => format!("bad `{verb}` arguments: {source}"),
            other => other.to_string(),
        })?;
        command.try_map(
            |l| {
                let package = base64::engine::general_purpose::STANDARD
                    .decode(l.package_b64.trim())
                    .map_err(|e| format!("package_b64 is not base64: {e}"))?;
                if package.is_empty() {
                    return Err("package_b64 is empty".into());
                }
                Ok(package)
            },
            Ok,
        )
    }

    /// The reply to a command, as published: `ok`, `verb`, `request_id`, `correlation` (if
    /// given), and `result` or `error`.
    pub fn reply(handle: &ReplyHandle, outcome: &Outcome) -> Reply {
        let reply = match outcome {
            Ok(result) => Reply::ok(&handle.verb, handle.request_id, result.clone()),
            Err(e) => Reply::err(&handle.verb, handle.request_id, e.code, e.message.clone()),
        };
        reply.with_correlation(handle.correlation.clone())
    }

    /// [`ControlPlane::reply`] as bytes.
    pub fn reply_payload(handle: &ReplyHandle, outcome: &Outcome) -> Vec<u8> {
        serde_json::to_vec(&Self::reply(handle, outcome)).unwrap_or_default()
    }

    /// The audit event of an accepted command.
    pub fn accepted_event(cmd: &IncomingCommand) -> EventMsg {
        let mut detail = json!({"verb": cmd.reply.verb, "request_id": cmd.reply.request_id, "key_id": cmd.key_id});
        // Only a signed envelope that names an account adds it, so the older form stands.
        if let (Some(a), Some(d)) = (&cmd.account, detail.as_object_mut()) {
            d.insert("account".into(), json!(a));
        }
        EventMsg {
            cycle: None,
            time_us: None,
            kind: EventKind::CommandReceived.into(),
            message: format!("{} received", cmd.reply.verb),
            detail,
        }
    }
}

/// A signed command's arguments, opened.
struct Unsealed {
    body: Map<String, Value>,
    key_id: String,
    account: Option<String>,
}

/// The arguments of a command that operator keys require to be signed: the envelope's payload,
/// with the key that signed it and the account it names. Nothing but the reply fields may stand
/// outside the envelope.
fn unseal(
    keys: &mut OperatorKeys,
    plc: &str,
    verb: Verb,
    obj: &Map<String, Value>,
    handle: &ReplyHandle,
    now_unix_s: u64,
) -> Result<Unsealed, (ErrorCode, String)> {
    let Some(env) = obj.get("envelope") else {
        return Err((
            ErrorCode::Unauthorised,
            "operator keys are configured: the command must be a signed envelope".into(),
        ));
    };
    if let Some(k) = obj
        .keys()
        .find(|k| !ReplyFields::META_FIELDS.contains(&k.as_str()))
    {
        return Err((
            ErrorCode::NotAllowed,
            format!(
                "`{}` stands outside the signed envelope; with operator keys every argument \
                 must be inside the signed payload",
                k.chars().take(64).collect::<String>()
            ),
        ));
    }
    let env = parse_envelope(env)?;
    // What the signature binds the command to: MQTT 5 correlation data, or the compact JSON of
    // an MQTT 3.1.1 client's `correlation` field.
    let correlation = match (&handle.correlation_data, &handle.correlation) {
        (Some(data), _) => data.clone(),
        (None, Some(c)) => c.to_string().into_bytes(),
        (None, None) => Vec::new(),
    };
    let (inner, key_id, account) =
        keys.verify(plc, verb.as_str(), &correlation, &env, now_unix_s)?;
    match serde_json::from_slice(&inner) {
        Ok(Value::Object(body)) => Ok(Unsealed {
            body,
            key_id,
            account,
        }),
        Ok(_) => Err((
            ErrorCode::Malformed,
            "signed payload must be a JSON object".into(),
        )),
        Err(e) => Err((
            ErrorCode::Malformed,
            format!("signed payload is not JSON: {e}"),
        )),
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

    /// A reply topic this PLC accepts.
    const R: &str = "cetratus/cell1/reply/test";

    fn cp() -> ControlPlane {
        ControlPlane::new("cell1", None).expect("valid id")
    }

    fn code(r: Result<IncomingCommand, Box<Rejection>>) -> ErrorCode {
        match r {
            Ok(c) => panic!("accepted: {c:?}"),
            Err(rej) => rej.reply.expect("a reply").1.code,
        }
    }

    #[test]
    fn a_load_with_reply_to_parses_into_the_package_bytes() {
        let p =
            br#"{"package_b64":"aGVsbG8=","reply_to":"cetratus/cell1/reply/me","correlation":42}"#;
        let c = cp()
            .parse("cetratus/cell1/cmd/load", p, None, None, 0)
            .expect("accepted");
        assert_eq!(c.request, Request::Load(b"hello".to_vec()));
        assert_eq!(c.reply.topic.as_deref(), Some("cetratus/cell1/reply/me"));
        assert_eq!(c.reply.correlation, Some(json!(42)));
    }

    #[test]
    fn the_mqtt5_response_topic_wins_over_reply_to() {
        let c = cp()
            .parse(
                "cetratus/cell1/cmd/abort",
                br#"{"reply_to":"cetratus/cell1/reply/x"}"#,
                Some("cetratus/cell1/reply/v5"),
                Some(b"c1"),
                0,
            )
            .expect("accepted");
        assert_eq!(c.reply.topic.as_deref(), Some("cetratus/cell1/reply/v5"));
        assert_eq!(c.reply.correlation_data.as_deref(), Some(&b"c1"[..]));
    }

    #[test]
    fn bad_commands_get_the_right_error_codes() {
        let r = Some(R);
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
            code(cp().parse("cetratus/cell1/cmd/load", p, Some(R), None, 0)),
            ErrorCode::NotAllowed
        );
    }

    #[test]
    fn a_rejection_without_reply_address_still_makes_an_event() {
        let rej = cp()
            .parse("cetratus/cell1/cmd/load", b"nope", None, None, 0)
            .expect_err("rejected");
        assert!(rej.reply.is_none());
        assert_eq!(rej.event.kind, EventKind::CommandRejected);
    }

    #[test]
    fn with_operator_keys_an_unsigned_command_is_unauthorised_and_a_signed_one_passes() {
        let sk = ed25519_dalek::SigningKey::from_bytes(&[5u8; 32]);
        let mut keys = OperatorKeys::new(Duration::from_secs(30));
        keys.add("op", sk.verifying_key());
        let mut cp = ControlPlane::new("cell1", Some(keys)).expect("valid id");
        assert_eq!(
            code(cp.parse("cetratus/cell1/cmd/abort", b"{}", Some(R), None, 100)),
            ErrorCode::Unauthorised
        );
        let signed = crate::Signed {
            plc: "cell1",
            verb: "abort",
            correlation: b"corr-1",
            timestamp: 100,
            nonce: "n-123456",
            account: None,
        };
        let env = crate::envelope::sign(&signed, b"{}", "op", &sk);
        let payload = serde_json::to_vec(&json!({"envelope": env})).expect("serialisable");
        // The same envelope, sent to another PLC or with other correlation data, is refused.
        let mut other = ControlPlane::new("cell2", cp.keys.clone()).expect("valid id");
        assert_eq!(
            code(other.parse(
                "cetratus/cell2/cmd/abort",
                &payload,
                Some("cetratus/cell2/reply/x"),
                Some(b"corr-1"),
                100
            )),
            ErrorCode::Unauthorised
        );
        assert_eq!(
            code(cp.parse(
                "cetratus/cell1/cmd/abort",
                &payload,
                Some(R),
                Some(b"corr-2"),
                100
            )),
            ErrorCode::Unauthorised
        );
        let c = cp
            .parse(
                "cetratus/cell1/cmd/abort",
                &payload,
                Some(R),
                Some(b"corr-1"),
                100,
            )
            .expect("accepted");
        assert_eq!(c.key_id.as_deref(), Some("op"));
        assert_eq!(
            code(cp.parse(
                "cetratus/cell1/cmd/abort",
                &payload,
                Some(R),
                Some(b"corr-1"),
                100
            )),
            ErrorCode::Replayed
        );
    }

    #[test]
    fn a_reply_topic_outside_this_plcs_reply_level_is_refused_and_not_answered() {
        for foreign in [
            "ops/r",
            "cetratus/cell2/reply/x",
            "cetratus/cell1/state",
            "cetratus/cell1/reply/",
        ] {
            let rej = cp()
                .parse("cetratus/cell1/cmd/abort", b"{}", Some(foreign), None, 0)
                .expect_err(foreign);
            assert!(rej.reply.is_none(), "{foreign}");
            assert_eq!(rej.event.detail["code"], "not_allowed", "{foreign}");
        }
        let p = br#"{"reply_to":"cetratus/cell2/reply/x"}"#;
        assert!(cp()
            .parse("cetratus/cell1/cmd/abort", p, None, None, 0)
            .is_err());
    }

    #[test]
    fn with_operator_keys_arguments_outside_the_envelope_and_v1_envelopes_are_refused() {
        let sk = ed25519_dalek::SigningKey::from_bytes(&[5u8; 32]);
        let mut keys = OperatorKeys::new(Duration::from_secs(30));
        keys.add("op", sk.verifying_key());
        let mut cp = ControlPlane::new("cell1", Some(keys)).expect("valid id");
        let signed = crate::Signed {
            plc: "cell1",
            verb: "substitute",
            correlation: b"",
            timestamp: 100,
            nonce: "n-654321",
            account: None,
        };
        let env = crate::envelope::sign(&signed, b"{}", "op", &sk);
        let outside = json!({"envelope": env, "force": true});
        let payload = serde_json::to_vec(&outside).expect("serialisable");
        assert_eq!(
            code(cp.parse(
                "cetratus/cell1/cmd/substitute",
                &payload,
                Some(R),
                None,
                100
            )),
            ErrorCode::NotAllowed
        );
        let mut v1 = serde_json::to_value(&env).expect("serialisable");
        v1.as_object_mut().expect("object").remove("v");
        let payload = serde_json::to_vec(&json!({"envelope": v1})).expect("serialisable");
        let rej = cp
            .parse(
                "cetratus/cell1/cmd/substitute",
                &payload,
                Some(R),
                None,
                100,
            )
            .expect_err("v1");
        let (_, e) = rej.reply.expect("a reply");
        assert_eq!(e.code, ErrorCode::Unauthorised);
        assert!(e.message.contains("upgrade"), "{}", e.message);
    }

    #[test]
    fn a_plc_id_with_topic_wildcards_is_refused() {
        assert!(ControlPlane::new("a/b", None).is_err());
        assert!(ControlPlane::new("", None).is_err());
    }
}
