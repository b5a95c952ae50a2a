//! Signed command envelopes: ed25519 over (verb, SHA-256 of the payload, timestamp, nonce), checked
//! against the configured operator keys inside a replay window.
//!
//! A signed command is published as `{"envelope": {...}}` (plus `reply_to`/`correlation` for MQTT
//! 3.1.1 clients). The signature covers the verb, so a signed `remove` cannot be replayed as a
//! `substitute`, and the nonce, so the same command cannot be replayed inside the window.

use std::collections::{BTreeMap, HashMap};
use std::time::Duration;

use base64::Engine as _;
use ed25519_dalek::{Signature, Signer as _, SigningKey, Verifier as _, VerifyingKey};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::MctError;
use cetratus_proto::ErrorCode;

/// Domain separation, so a command signature can never be mistaken for any other signature.
const CONTEXT: &str = "cetratus-cmd-v1";

/// A signed command as it travels in the `envelope` field.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Envelope {
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
}

/// The bytes an operator signs.
pub fn signing_message(verb: &str, payload: &[u8], timestamp: u64, nonce: &str) -> Vec<u8> {
    let digest = hex::encode(Sha256::digest(payload));
    format!("{CONTEXT}\n{verb}\n{digest}\n{timestamp}\n{nonce}").into_bytes()
}

/// Signs a command body: what an operator tool (or a test) does.
pub fn sign(
    verb: &str,
    payload: &[u8],
    timestamp: u64,
    nonce: &str,
    key_id: &str,
    key: &SigningKey,
) -> Envelope {
    let b64 = base64::engine::general_purpose::STANDARD;
    let sig = key.sign(&signing_message(verb, payload, timestamp, nonce));
    Envelope {
        key_id: key_id.to_string(),
        payload_b64: b64.encode(payload),
        timestamp,
        nonce: nonce.to_string(),
        signature: b64.encode(sig.to_bytes()),
    }
}

/// The operator keys and the nonces seen inside the replay window.
#[derive(Debug, Clone)]
pub struct OperatorKeys {
    keys: BTreeMap<String, VerifyingKey>,
    window_s: u64,
    // Nonce → timestamp; pruned as the window moves so it stays small.
    seen: HashMap<String, u64>,
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

    /// Checks an envelope for `verb` at Unix time `now_s`; returns the signed body and the key id.
    pub fn verify(
        &mut self,
        verb: &str,
        env: &Envelope,
        now_s: u64,
    ) -> Result<(Vec<u8>, String), (ErrorCode, String)> {
        let unauth = |m: String| (ErrorCode::Unauthorised, m);
        let key = self
            .keys
            .get(&env.key_id)
            .ok_or_else(|| unauth(format!("unknown operator key `{}`", env.key_id)))?;
        if !(8..=64).contains(&env.nonce.len()) {
            return Err(unauth("the nonce must be 8 to 64 characters".into()));
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
        key.verify(
            &signing_message(verb, &payload, env.timestamp, &env.nonce),
            &sig,
        )
        .map_err(|_| {
            unauth(format!(
                "the signature does not verify with key `{}` for verb `{verb}`",
                env.key_id
            ))
        })?;
        // Only a verified command may consume a nonce, so forgeries cannot burn someone else's nonces.
        let window = self.window_s;
        self.seen.retain(|_, ts| ts.abs_diff(now_s) <= window);
        if self.seen.contains_key(&env.nonce) {
            return Err((
                ErrorCode::Replayed,
                format!(
                    "nonce `{}` was already used inside the replay window",
                    env.nonce
                ),
            ));
        }
        self.seen.insert(env.nonce.clone(), env.timestamp);
        Ok((payload, env.key_id.clone()))
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

    #[test]
    fn a_signed_command_verifies_and_yields_its_body_and_key_id() {
        let (mut k, sk) = keys();
        let env = sign("remove", b"{}", 1000, "nonce-0001", "op1", &sk);
        assert_eq!(
            k.verify("remove", &env, 1010),
            Ok((b"{}".to_vec(), "op1".to_string()))
        );
    }

    #[test]
    fn a_replayed_nonce_is_refused() {
        let (mut k, sk) = keys();
        let env = sign("abort", b"{}", 1000, "nonce-0002", "op1", &sk);
        assert!(k.verify("abort", &env, 1000).is_ok());
        assert_eq!(
            k.verify("abort", &env, 1001).map_err(|e| e.0),
            Err(ErrorCode::Replayed)
        );
    }

    #[test]
    fn a_signature_for_another_verb_is_refused() {
        let (mut k, sk) = keys();
        let env = sign("remove", b"{}", 1000, "nonce-0003", "op1", &sk);
        assert_eq!(
            k.verify("substitute", &env, 1000).map_err(|e| e.0),
            Err(ErrorCode::Unauthorised)
        );
    }

    #[test]
    fn a_tampered_payload_is_refused() {
        let (mut k, sk) = keys();
        let mut env = sign(
            "substitute",
            br#"{"mode":"retransform"}"#,
            1000,
            "nonce-0004",
            "op1",
            &sk,
        );
        env.payload_b64 =
            base64::engine::general_purpose::STANDARD.encode(br#"{"mode":"keep","force":true}"#);
        assert_eq!(
            k.verify("substitute", &env, 1000).map_err(|e| e.0),
            Err(ErrorCode::Unauthorised)
        );
    }

    #[test]
    fn a_stale_timestamp_is_refused() {
        let (mut k, sk) = keys();
        let env = sign("reset", b"{}", 1000, "nonce-0005", "op1", &sk);
        assert_eq!(
            k.verify("reset", &env, 1031).map_err(|e| e.0),
            Err(ErrorCode::Unauthorised)
        );
    }

    #[test]
    fn an_unknown_key_is_refused() {
        let (mut k, _) = keys();
        let other = SigningKey::from_bytes(&[9u8; 32]);
        let env = sign("reset", b"{}", 1000, "nonce-0006", "mallory", &other);
        assert_eq!(
            k.verify("reset", &env, 1000).map_err(|e| e.0),
            Err(ErrorCode::Unauthorised)
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
