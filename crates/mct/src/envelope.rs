//! Signed command envelopes, version 2: ed25519 over the domain tag `cetratus-cmd-v2`, the PLC id,
//! the verb, the SHA-256 of the payload, the MQTT correlation data, the timestamp and a nonce,
//! checked against the configured operator keys inside a replay window.
//!
//! A signed command is published as `{"envelope": {...}}` (plus `reply_to`/`correlation` for MQTT
//! 3.1.1 clients, and nothing else: arguments go inside the signed payload). What is signed
//! decides what cannot be reused: the PLC id, so a command for one PLC does not replay to another;
//! the verb, so a signed `remove` cannot become a `substitute`; the correlation data, so a
//! captured command cannot be re-sent to steer someone else's pending request; the nonce, tracked
//! per key, so the same command cannot be replayed inside the window.
//!
//! An envelope may also name the `account` of the operator the signing tool acted for (the
//! dashboard signs with one key for every logged-in operator). It is signed as one more line,
//! `account:<name>`, after the nonce; an envelope without it signs exactly what version 2 always
//! signed, so envelopes of older clients stay valid. Neither the nonce nor the account may hold a
//! line end, so no two envelopes sign the same bytes.

use std::collections::{BTreeMap, HashMap};
use std::time::Duration;

use base64::Engine as _;
use ed25519_dalek::{Signature, Signer as _, SigningKey, Verifier as _, VerifyingKey};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::MctError;
use cetratus_proto::ErrorCode;

/// Domain separation, so a command signature can never be mistaken for any other signature.
const CONTEXT: &str = "cetratus-cmd-v2";

/// The envelope version this PLC signs and accepts.
pub const ENVELOPE_VERSION: u32 = 2;

/// A signed command as it travels in the `envelope` field.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Envelope {
    /// The envelope version: 2.
    pub v: u32,
    /// Which operator key signed it.
    pub key_id: String,
    /// The command's JSON body, base64 (standard alphabet): the exact bytes that were hashed.
    pub payload_b64: String,
    /// Unix time of signing, in seconds.
    pub timestamp: u64,
    /// A fresh random string (8 to 64 characters) per command.
    pub nonce: String,
    /// The ed25519 signature of [`signing_message`], base64.
    pub signature: String,
    /// The account the signing tool acted for (a dashboard login), signed; absent for a tool
    /// that signs for its own key only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub account: Option<String>,
}

/// What a signature binds a command to, besides its payload.
#[derive(Clone, Copy, Debug)]
pub struct Signed<'a> {
    /// The PLC the command is for.
    pub plc: &'a str,
    /// The verb.
    pub verb: &'a str,
    /// The MQTT 5 correlation data of the request (empty when there is none; an MQTT 3.1.1 client
    /// signs the compact JSON of its `correlation` field).
    pub correlation: &'a [u8],
    /// Unix time of signing, in seconds.
    pub timestamp: u64,
    /// The nonce.
    pub nonce: &'a str,
    /// The account the command is signed for, if any: 1 to 64 letters, digits, `.`, `_`, `-`.
    pub account: Option<&'a str>,
}

/// Whether `name` may stand as an envelope's account: what dashboard accounts are named.
pub fn valid_account(name: &str) -> bool {
    (1..=64).contains(&name.len())
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'_' | b'-'))
}

/// The bytes an operator signs: one field a line, binary fields in hex.
pub fn signing_message(s: &Signed<'_>, payload: &[u8]) -> Vec<u8> {
    let digest = hex::encode(Sha256::digest(payload));
    let correlation = hex::encode(s.correlation);
    let mut m = format!(
        "{CONTEXT}\n{}\n{}\n{digest}\n{correlation}\n{}\n{}",
        s.plc, s.verb, s.timestamp, s.nonce
    );
    if let Some(a) = s.account {
        m.push_str("\naccount:");
        m.push_str(a);
    }
    m.into_bytes()
}

/// Signs a command body: what an operator tool (or a test) does.
pub fn sign(s: &Signed<'_>, payload: &[u8], key_id: &str, key: &SigningKey) -> Envelope {
    let b64 = base64::engine::general_purpose::STANDARD;
    let sig = key.sign(&signing_message(s, payload));
    Envelope {
        v: ENVELOPE_VERSION,
        key_id: key_id.to_string(),
        payload_b64: b64.encode(payload),
        timestamp: s.timestamp,
        nonce: s.nonce.to_string(),
        signature: b64.encode(sig.to_bytes()),
        account: s.account.map(str::to_string),
    }
}

/// Reads the `envelope` field of a command: a version-2 envelope, or a refusal that says what to
/// do (a version-1 envelope comes from a client that must be upgraded).
pub fn parse_envelope(v: &serde_json::Value) -> Result<Envelope, (ErrorCode, String)> {
    match v.get("v").and_then(serde_json::Value::as_u64) {
        None => {
            return Err((
                ErrorCode::Unauthorised,
                "this is a version-1 command envelope, which this PLC refuses: it does not name \
                 the PLC, so it could be replayed to another; upgrade the client (cetratus, the \
                 dashboard) so that it signs version-2 envelopes"
                    .into(),
            ))
        }
        Some(n) if n != u64::from(ENVELOPE_VERSION) => {
            return Err((
                ErrorCode::Unauthorised,
                format!("envelope version {n} is not known here; this PLC accepts version {ENVELOPE_VERSION}"),
            ))
        }
        Some(_) => {}
    }
    serde_json::from_value(v.clone())
        .map_err(|e| (ErrorCode::Malformed, format!("bad envelope: {e}")))
}

/// What a verified envelope yields: the signed body, the key id and the account it names.
pub type Verified = (Vec<u8>, String, Option<String>);

/// The operator keys and the nonces seen inside the replay window.
#[derive(Debug, Clone)]
pub struct OperatorKeys {
    keys: BTreeMap<String, VerifyingKey>,
    window_s: u64,
    // (key id, nonce) → timestamp: nonces are tracked per key, and pruned as the window moves. Only
    // verified commands add to it, so its size is bounded by what trusted operators sent within
    // one window.
    seen: HashMap<(String, String), u64>,
}

impl OperatorKeys {
    /// No keys yet; commands older or newer than `window` (either way) are refused.
    pub fn new(window: Duration) -> Self {
        OperatorKeys {
            keys: BTreeMap::new(),
            window_s: window.as_secs().max(1),
            seen: HashMap::new(),
        }
    }

    /// Adds a key.
    pub fn add(&mut self, id: &str, key: VerifyingKey) {
        self.keys.insert(id.to_string(), key);
    }

    /// Adds a key given as 64 hex digits (the 32-byte ed25519 public key), as in a config file.
    pub fn add_hex(&mut self, id: &str, hex_key: &str) -> Result<(), MctError> {
        let bad = |reason: String| MctError::OperatorKey {
            id: id.to_string(),
            reason,
        };
        let bytes = hex::decode(hex_key.trim()).map_err(|e| bad(format!("not hex: {e}")))?;
        let arr: [u8; 32] = bytes.try_into().map_err(|v: Vec<u8>| {
            bad(format!("{} bytes; an ed25519 public key has 32", v.len()))
        })?;
        let key = VerifyingKey::from_bytes(&arr)
            .map_err(|e| bad(format!("not an ed25519 point: {e}")))?;
        self.add(id, key);
        Ok(())
    }

    /// Whether any key is configured (then every command must be signed).
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// Checks an envelope for `verb` to PLC `plc` with the request's `correlation` data, at Unix
    /// time `now_s`; returns the signed body, the key id and the account it names.
    pub fn verify(
        &mut self,
        plc: &str,
        verb: &str,
        correlation: &[u8],
        env: &Envelope,
        now_s: u64,
    ) -> Result<Verified, (ErrorCode, String)> {
        let unauth = |m: String| (ErrorCode::Unauthorised, m);
        let key = self
            .keys
            .get(&env.key_id)
            .ok_or_else(|| unauth(format!("unknown operator key `{}`", env.key_id)))?;
        if !(8..=64).contains(&env.nonce.len()) || !env.nonce.bytes().all(|b| b.is_ascii_graphic())
        {
            return Err(unauth(
                "the nonce must be 8 to 64 printable ASCII characters".into(),
            ));
        }
        if let Some(a) = &env.account {
            if !valid_account(a) {
                return Err(unauth(
                    "the envelope's account must be 1 to 64 letters, digits, `.`, `_` or `-`"
                        .into(),
                ));
            }
        }
        if env.timestamp.abs_diff(now_s) > self.window_s {
            return Err(unauth(format!(
                "timestamp {} is outside the replay window of {} s around {now_s}; check the operator's clock",
                env.timestamp, self.window_s
            )));
        }
        let b64 = base64::engine::general_purpose::STANDARD;
        let payload = b64.decode(&env.payload_b64).map_err(|e| {
            (
                ErrorCode::Malformed,
                format!("payload_b64 is not base64: {e}"),
            )
        })?;
        let sig_bytes = b64
            .decode(&env.signature)
            .map_err(|e| unauth(format!("signature is not base64: {e}")))?;
        let sig =
            Signature::from_slice(&sig_bytes).map_err(|e| unauth(format!("bad signature: {e}")))?;
        let signed = Signed {
            plc,
            verb,
            correlation,
            timestamp: env.timestamp,
            nonce: &env.nonce,
            account: env.account.as_deref(),
        };
        key.verify(&signing_message(&signed, &payload), &sig)
            .map_err(|_| {
                unauth(format!(
                    "the signature does not verify with key `{}` for verb `{verb}` to PLC `{plc}` \
                     with this correlation data",
                    env.key_id
                ))
            })?;
        // Only a verified command may consume a nonce, so forgeries cannot burn someone else's nonces.
        let window = self.window_s;
        self.seen.retain(|_, ts| ts.abs_diff(now_s) <= window);
        let seen = (env.key_id.clone(), env.nonce.clone());
        if self.seen.contains_key(&seen) {
            return Err((
                ErrorCode::Replayed,
                format!(
                    "nonce `{}` was already used inside the replay window",
                    env.nonce
                ),
            ));
        }
        self.seen.insert(seen, env.timestamp);
        Ok((payload, env.key_id.clone(), env.account.clone()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keys() -> (OperatorKeys, SigningKey) {
        let sk = SigningKey::from_bytes(&[7u8; 32]);
        let mut k = OperatorKeys::new(Duration::from_secs(30));
        k.add("op1", sk.verifying_key());
        (k, sk)
    }

    fn signed<'a>(verb: &'a str, ts: u64, nonce: &'a str) -> Signed<'a> {
        Signed {
            plc: "cell1",
            verb,
            correlation: b"c-1",
            timestamp: ts,
            nonce,
            account: None,
        }
    }

    #[test]
    fn a_signed_command_verifies_and_yields_its_body_and_key_id() {
        let (mut k, sk) = keys();
        let env = sign(&signed("remove", 1000, "nonce-0001"), b"{}", "op1", &sk);
        assert_eq!(
            k.verify("cell1", "remove", b"c-1", &env, 1010),
            Ok((b"{}".to_vec(), "op1".to_string(), None))
        );
    }

    #[test]
    fn the_account_is_signed_and_cannot_be_changed_added_or_removed() {
        let (mut k, sk) = keys();
        let s = Signed {
            account: Some("alice"),
            ..signed("abort", 1000, "nonce-acct-1")
        };
        let env = sign(&s, b"{}", "op1", &sk);
        assert_eq!(
            k.verify("cell1", "abort", b"c-1", &env, 1000),
            Ok((b"{}".to_vec(), "op1".to_string(), Some("alice".to_string())))
        );
        let s = Signed {
            account: Some("alice"),
            ..signed("abort", 1000, "nonce-acct-2")
        };
        let mut changed = sign(&s, b"{}", "op1", &sk);
        changed.account = Some("bob".into());
        let mut removed = changed.clone();
        removed.account = None;
        let mut added = sign(&signed("abort", 1000, "nonce-acct-3"), b"{}", "op1", &sk);
        added.account = Some("alice".into());
        for env in [changed, removed, added] {
            assert_eq!(
                k.verify("cell1", "abort", b"c-1", &env, 1000)
                    .map_err(|e| e.0),
                Err(ErrorCode::Unauthorised),
                "{env:?}"
            );
        }
        let mut newline = sign(&signed("abort", 1000, "nonce-acct-4"), b"{}", "op1", &sk);
        newline.account = Some("a\nb".into());
        assert!(k.verify("cell1", "abort", b"c-1", &newline, 1000).is_err());
    }

    #[test]
    fn a_replayed_nonce_is_refused() {
        let (mut k, sk) = keys();
        let env = sign(&signed("abort", 1000, "nonce-0002"), b"{}", "op1", &sk);
        assert!(k.verify("cell1", "abort", b"c-1", &env, 1000).is_ok());
        assert_eq!(
            k.verify("cell1", "abort", b"c-1", &env, 1001)
                .map_err(|e| e.0),
            Err(ErrorCode::Replayed)
        );
    }

    #[test]
    fn nonces_are_tracked_per_key() {
        let (mut k, sk) = keys();
        let other = SigningKey::from_bytes(&[8u8; 32]);
        k.add("op2", other.verifying_key());
        let a = sign(&signed("abort", 1000, "nonce-same"), b"{}", "op1", &sk);
        let b = sign(&signed("abort", 1000, "nonce-same"), b"{}", "op2", &other);
        assert!(k.verify("cell1", "abort", b"c-1", &a, 1000).is_ok());
        assert!(k.verify("cell1", "abort", b"c-1", &b, 1000).is_ok());
    }

    #[test]
    fn a_command_signed_for_another_plc_is_refused() {
        let (mut k, sk) = keys();
        let env = sign(&signed("remove", 1000, "nonce-0007"), b"{}", "op1", &sk);
        assert_eq!(
            k.verify("cell2", "remove", b"c-1", &env, 1000)
                .map_err(|e| e.0),
            Err(ErrorCode::Unauthorised)
        );
    }

    #[test]
    fn a_command_resent_with_other_correlation_data_is_refused() {
        let (mut k, sk) = keys();
        let env = sign(&signed("remove", 1000, "nonce-0008"), b"{}", "op1", &sk);
        assert_eq!(
            k.verify("cell1", "remove", b"c-2", &env, 1000)
                .map_err(|e| e.0),
            Err(ErrorCode::Unauthorised)
        );
    }

    #[test]
    fn a_signature_for_another_verb_is_refused() {
        let (mut k, sk) = keys();
        let env = sign(&signed("remove", 1000, "nonce-0003"), b"{}", "op1", &sk);
        assert_eq!(
            k.verify("cell1", "substitute", b"c-1", &env, 1000)
                .map_err(|e| e.0),
            Err(ErrorCode::Unauthorised)
        );
    }

    #[test]
    fn a_tampered_payload_is_refused() {
        let (mut k, sk) = keys();
        let mut env = sign(
            &signed("substitute", 1000, "nonce-0004"),
            br#"{"mode":"retransform"}"#,
            "op1",
            &sk,
        );
        env.payload_b64 =
            base64::engine::general_purpose::STANDARD.encode(br#"{"mode":"keep","force":true}"#);
        assert_eq!(
            k.verify("cell1", "substitute", b"c-1", &env, 1000)
                .map_err(|e| e.0),
            Err(ErrorCode::Unauthorised)
        );
    }

    #[test]
    fn a_stale_timestamp_is_refused() {
        let (mut k, sk) = keys();
        let env = sign(&signed("reset", 1000, "nonce-0005"), b"{}", "op1", &sk);
        assert_eq!(
            k.verify("cell1", "reset", b"c-1", &env, 1031)
                .map_err(|e| e.0),
            Err(ErrorCode::Unauthorised)
        );
    }

    #[test]
    fn an_unknown_key_is_refused() {
        let (mut k, _) = keys();
        let other = SigningKey::from_bytes(&[9u8; 32]);
        let env = sign(
            &signed("reset", 1000, "nonce-0006"),
            b"{}",
            "mallory",
            &other,
        );
        assert_eq!(
            k.verify("cell1", "reset", b"c-1", &env, 1000)
                .map_err(|e| e.0),
            Err(ErrorCode::Unauthorised)
        );
    }

    #[test]
    fn a_version_1_envelope_is_refused_with_what_to_do() {
        let v1 = serde_json::json!({"key_id": "op1", "payload_b64": "e30=", "timestamp": 1,
            "nonce": "nonce-0009", "signature": "AA=="});
        let (code, message) = parse_envelope(&v1).unwrap_err();
        assert_eq!(code, ErrorCode::Unauthorised);
        assert!(
            message.contains("version-1") && message.contains("upgrade"),
            "{message}"
        );
    }

    #[test]
    fn a_key_from_config_must_be_32_hex_bytes() {
        let mut k = OperatorKeys::new(Duration::from_secs(30));
        assert!(k.add_hex("x", "abcd").is_err());
        let sk = SigningKey::from_bytes(&[3u8; 32]);
        assert!(k
            .add_hex("x", &hex::encode(sk.verifying_key().to_bytes()))
            .is_ok());
    }
}
