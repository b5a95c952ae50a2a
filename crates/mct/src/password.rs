//! Password hashes, one home for the embedded broker's accounts and the dashboard's: argon2id,
//! written as PHC strings (`$argon2id$v=19$m=19456,t=2,p=1$<salt>$<hash>`), as
//! `cetratus hash-password` prints them.
//!
//! Checking one costs about 19 MiB and tens of milliseconds on purpose, so callers check them off
//! any thread that matters (a blocking thread, one at a time) and limit how often they may.

use argon2::password_hash::{PasswordHash, PasswordHashString, PasswordHasher, PasswordVerifier};
use argon2::Argon2;

/// What is wrong with a password hash, or why hashing failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PasswordError {
    /// Not a PHC string at all.
    #[error("not a PHC string ({0})")]
    NotPhc(String),
    /// A PHC string of another algorithm.
    #[error("the algorithm is `{0}`, not argon2")]
    NotArgon2(String),
    /// The system gave no randomness for the salt, or argon2 refused the parameters.
    #[error("cannot hash the password: {0}")]
    Hashing(String),
}

/// A password hash that parsed as an argon2 PHC string.
#[derive(Clone, Debug)]
pub struct HashedPassword(PasswordHashString);

impl HashedPassword {
    /// Reads a PHC string; anything but an argon2 hash is refused, with the reason.
    pub fn parse(phc: &str) -> Result<Self, PasswordError> {
        let h = PasswordHash::new(phc).map_err(|e| PasswordError::NotPhc(e.to_string()))?;
        if !h.algorithm.as_str().starts_with("argon2") {
            return Err(PasswordError::NotArgon2(h.algorithm.to_string()));
        }
        Ok(HashedPassword(h.serialize()))
    }

    /// The hash that stands in for an unknown account, so that a wrong name costs what a wrong
    /// password does.
    pub fn decoy() -> Self {
        const DECOY: &str = "$argon2id$v=19$m=19456,t=2,p=1$c29tZXNhbHRzb21lc2FsdA$0XzFlcxA4ud8sQUEA0Mh3kydlsDtqHZ2d9LV1Fm5bfg";
        match PasswordHash::new(DECOY) {
            Ok(h) => HashedPassword(h.serialize()),
            // A constant that parses in the test below; unreachable.
            Err(_) => unreachable!("the decoy hash is a valid PHC string"),
        }
    }

    /// Whether `password` hashes to this. Slow on purpose: run it on a blocking thread.
    pub fn verify(&self, password: &[u8]) -> bool {
        Argon2::default()
            .verify_password(password, &self.0.password_hash())
            .is_ok()
    }
}

/// The argon2id hash of `password` with a fresh salt, as a PHC string.
pub fn hash_password(password: &str) -> Result<String, PasswordError> {
    use argon2::password_hash::SaltString;
    let failed = |e: &dyn std::fmt::Display| PasswordError::Hashing(e.to_string());
    let mut salt = [0u8; 16];
    getrandom::fill(&mut salt).map_err(|e| failed(&e))?;
    let salt = SaltString::encode_b64(&salt).map_err(|e| failed(&e))?;
    Argon2::default()
        .hash_password(password.as_bytes(), &salt)
        .map(|h| h.to_string())
        .map_err(|e| failed(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hash_verifies_its_password_only() {
        let h = HashedPassword::parse(&hash_password("s3cret").expect("hashes")).expect("parses");
        assert!(h.verify(b"s3cret"));
        assert!(!h.verify(b"s3cret "));
        assert!(!HashedPassword::decoy().verify(b"s3cret"));
    }

    #[test]
    fn only_argon2_phc_strings_are_hashes() {
        assert!(HashedPassword::parse("s3cret").is_err());
        let e = HashedPassword::parse("$pbkdf2-sha256$i=1000$c2FsdHNhbHQ$aGFzaGhhc2hoYXNo")
            .expect_err("not argon2");
        assert!(e.to_string().contains("pbkdf2"), "{e}");
    }
}
