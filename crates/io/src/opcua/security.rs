//! How OPC UA clients are let in (docs/security.md, *OPC UA*).
//!
//! * Security `none` (loopback only, checked when the configuration is read): one endpoint with
//!   policy None, anonymous sessions.
//! * Security `sign-and-encrypt`: one endpoint per configured policy (Basic256Sha256,
//!   Aes128_Sha256_RsaOaep, Aes256_Sha256_RsaPss), all Sign & Encrypt. A client's application
//!   certificate must be in the trust list (`<pki>/trusted/`, any `.der` name at start);
//!   unknown certificates are refused and kept in `<pki>/rejected/` for an administrator to move. With `[[opcua.user]]`
//!   entries a session logs in as one of them (argon2 hashes, checked on a blocking thread);
//!   without, the trusted certificate is the credential.

use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use async_trait::async_trait;
use opcua::server::authenticator::{
    user_pass_security_policy_id, user_pass_security_policy_uri, AuthManager, Password, UserToken,
};
use opcua::server::{ServerBuilder, ServerEndpoint, ServerUserToken, ANONYMOUS_USER_TOKEN_ID};
use opcua::types::{Error, StatusCode, UAString, UserTokenPolicy, UserTokenType};

use super::config::{OpcUaConfig, Policy, Security, User};
use super::limit::LOGINS;
use super::{PasswordCheck, Shared};
use cetratus_slots::rate::{worth_logging, TokenBucket};

/// The endpoint token id of users with passwords.
const USERS: &str = "cetratus-users";

/// Sets the endpoints, the PKI and the authenticator of `config` on `builder`.
pub(crate) fn configure(
    builder: ServerBuilder,
    config: &OpcUaConfig,
    passwords: Option<PasswordCheck>,
    shared: Arc<Shared>,
) -> Result<ServerBuilder, String> {
    match &config.security {
        Security::None => Ok(builder
            // Policy None uses no certificate; the store still wants a directory.
            .pki_dir(std::env::temp_dir().join("cetratus-opcua-none"))
            .add_endpoint(
                "none",
                ServerEndpoint::new_none("/", &[ANONYMOUS_USER_TOKEN_ID.to_string()]),
            )),
        Security::SignAndEncrypt { policies, pki } => {
            let check = match (&config.users[..], passwords) {
                ([], _) => None,
                (_, Some(c)) => Some(c),
                (_, None) => {
                    return Err("users with passwords need the password check of the node".into())
                }
            };
            let ids = [if check.is_some() {
                USERS.to_string()
            } else {
                ANONYMOUS_USER_TOKEN_ID.to_string()
            }];
            // Certificates an administrator copied into trusted/ under another name than the one
            // async-opcua looks for are added under it (at start).
            super::pki::install_trusted(&absolute(pki)).map_err(|e| e.to_string())?;
            let mut b = builder
                // The endpoints name their token by id; async-opcua checks that one is
                // configured. Its password is never compared: `Accounts` decides every login.
                .add_user_token(
                    USERS,
                    ServerUserToken {
                        user: USERS.to_string(),
                        pass: Some(unguessable()),
                        ..Default::default()
                    },
                )
                .pki_dir(absolute(pki))
                .create_sample_keypair(true)
                .trust_client_certs(false)
                .with_authenticator(Arc::new(Accounts {
                    users: config.users.clone(),
                    check,
                    rate: Mutex::new(TokenBucket::new(LOGINS, Instant::now())),
                    shared,
                }));
            for p in policies {
                let (id, e) = match p {
                    Policy::Basic256Sha256 => (
                        "basic256sha256",
                        ServerEndpoint::new_basic256sha256_sign_encrypt("/", &ids),
                    ),
                    Policy::Aes128Sha256RsaOaep => (
                        "aes128sha256rsaoaep",
                        ServerEndpoint::new_aes128_sha256_rsaoaep_sign_encrypt("/", &ids),
                    ),
                    Policy::Aes256Sha256RsaPss => (
                        "aes256sha256rsapss",
                        ServerEndpoint::new_aes256_sha256_rsapss_sign_encrypt("/", &ids),
                    ),
                };
                b = b.add_endpoint(id, e);
            }
            Ok(b)
        }
    }
}

/// A password no one knows (std's hasher keys are random per process).
fn unguessable() -> String {
    use std::hash::BuildHasher;
    let (a, b) = (
        std::collections::hash_map::RandomState::new().hash_one(1u8),
        std::collections::hash_map::RandomState::new().hash_one(2u8),
    );
    format!("{a:016x}{b:016x}")
}

fn absolute(p: &std::path::Path) -> PathBuf {
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        std::env::current_dir()
            .map(|d| d.join(p))
            .unwrap_or_else(|_| p.to_path_buf())
    }
}

/// The users of an encrypted server; without users, anonymous sessions over a trusted
/// certificate.
struct Accounts {
    users: Vec<User>,
    check: Option<PasswordCheck>,
    /// Password checks for all clients together (async-opcua does not tell an authenticator
    /// which address a login comes from; the front listener limits connections per address).
    rate: Mutex<TokenBucket>,
    shared: Arc<Shared>,
}

#[async_trait]
impl AuthManager for Accounts {
    async fn authenticate_anonymous_token(&self, _endpoint: &ServerEndpoint) -> Result<(), Error> {
        if self.check.is_none() {
            Ok(())
        } else {
            Err(Error::new(
                StatusCode::BadIdentityTokenRejected,
                "log in as a user",
            ))
        }
    }

    async fn authenticate_username_identity_token(
        &self,
        _endpoint: &ServerEndpoint,
        username: &str,
        password: &Password,
    ) -> Result<UserToken, Error> {
        let rejected = || Error::new(StatusCode::BadUserAccessDenied, "wrong user or password");
        let Some(check) = self.check.clone() else {
            return Err(rejected());
        };
        let counters = &self.shared.counters;
        let may = self
            .rate
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take(1.0, Instant::now());
        if !may {
            // Refused before the (slow) check, counted, and logged on the 1st, 2nd, 4th…
            // refusal: a flood of guesses must not become a flood of log lines.
            let n = counters.refused_logins.fetch_add(1, Ordering::Relaxed) + 1;
            if worth_logging(n) {
                tracing::warn!(user = %username.escape_debug(), refused = n, "OPC UA login refused: too many attempts");
            }
            // Answered as a wrong password is (async-opcua reports a refused identity as
            // BadUserAccessDenied): a guesser learns nothing from it.
            return Err(Error::new(
                StatusCode::BadUserAccessDenied,
                "too many login attempts; try again in a few seconds",
            ));
        }
        // An unknown name costs what a wrong password does: the check runs on some hash.
        let (known, hash) = match self.users.iter().find(|u| u.name == username) {
            Some(u) => (true, u.password_hash.clone()),
            None => (
                false,
                self.users
                    .first()
                    .map(|u| u.password_hash.clone())
                    .unwrap_or_default(),
            ),
        };
        let password = password.get().as_bytes().to_vec();
        let ok = tokio::task::spawn_blocking(move || check(&hash, &password))
            .await
            .unwrap_or(false);
        if ok && known {
            counters.logins.fetch_add(1, Ordering::Relaxed);
            tracing::info!(user = %username, "OPC UA login");
            Ok(UserToken(username.to_string()))
        } else {
            let n = counters.failed_logins.fetch_add(1, Ordering::Relaxed) + 1;
            if worth_logging(n) {
                tracing::warn!(user = %username.escape_debug(), failed = n, "OPC UA login failed: wrong user or password");
            }
            Err(rejected())
        }
    }

    fn user_token_policies(&self, endpoint: &ServerEndpoint) -> Vec<UserTokenPolicy> {
        if self.check.is_some() {
            vec![UserTokenPolicy {
                policy_id: user_pass_security_policy_id(endpoint),
                token_type: UserTokenType::UserName,
                issued_token_type: UAString::null(),
                issuer_endpoint_url: UAString::null(),
                security_policy_uri: user_pass_security_policy_uri(endpoint),
            }]
        } else {
            vec![UserTokenPolicy {
                policy_id: UAString::from("anonymous"),
                token_type: UserTokenType::Anonymous,
                issued_token_type: UAString::null(),
                issuer_endpoint_url: UAString::null(),
                security_policy_uri: UAString::null(),
            }]
        }
    }
}
