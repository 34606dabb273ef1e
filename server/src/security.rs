//! Who may plan: TLS (optionally mutual) on the gRPC port and a bearer
//! token checked on the planner service. Health and reflection stay open to
//! probes; the metrics port is separate and plaintext.

use std::{path::Path, sync::Arc};

use prometheus::IntCounter;
use tonic::{
    Request, Status,
    service::Interceptor,
    transport::{Certificate, Identity, ServerTlsConfig},
};

use crate::{
    error::{Error, Result},
    settings::SecuritySettings,
};

/// The security settings with their files read.
#[derive(Debug, Default)]
pub struct Loaded {
    /// TLS for the gRPC port, if configured.
    pub tls: Option<ServerTlsConfig>,
    /// The bearer token planning calls must send, if configured.
    pub token: Option<String>,
}

fn read(key: &str, path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| Error::Startup(format!("`security.{key}` {}: {e}", path.display())))
}

/// Reads the certificate, key, CA and token files the settings name.
pub fn load(settings: &SecuritySettings) -> Result<Loaded> {
    let tls = match (&settings.tls_cert, &settings.tls_key) {
        (Some(cert), Some(key)) => {
            let identity = Identity::from_pem(read("tls_cert", cert)?, read("tls_key", key)?);
            let mut tls = ServerTlsConfig::new().identity(identity);
            if let Some(ca) = &settings.tls_client_ca {
                tls = tls.client_ca_root(Certificate::from_pem(read("tls_client_ca", ca)?));
            }
            Some(tls)
        }
        _ => None,
    };
    let token = match &settings.bearer_token_file {
        Some(path) => {
            let text = String::from_utf8(read("bearer_token_file", path)?).map_err(|_| {
                Error::Startup(format!(
                    "`security.bearer_token_file` {}: not UTF-8",
                    path.display()
                ))
            })?;
            let token = text.trim().to_owned();
            if token.is_empty() || token.chars().any(|c| c.is_whitespace() || c.is_control()) {
                return Err(Error::Startup(format!(
                    "`security.bearer_token_file` {}: the token must be one non-empty word",
                    path.display()
                )));
            }
            Some(token)
        }
        None => None,
    };
    Ok(Loaded { tls, token })
}

/// Checks `authorization: Bearer <token>` on every call of the service it
/// wraps (a no-op without a token); refusals are UNAUTHENTICATED and counted.
#[derive(Debug, Clone)]
pub struct BearerAuth {
    expected: Option<Arc<[u8]>>,
    refused: IntCounter,
}

impl BearerAuth {
    /// Checks for `token` (none: lets every call through).
    pub fn new(token: Option<String>, refused: IntCounter) -> Self {
        Self {
            expected: token.map(|t| Arc::from(format!("Bearer {t}").into_bytes())),
            refused,
        }
    }
}

/// Equal bytes, in time independent of where they first differ.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

impl Interceptor for BearerAuth {
    fn call(&mut self, request: Request<()>) -> Result<Request<()>, Status> {
        let Some(expected) = &self.expected else {
            return Ok(request);
        };
        match request.metadata().get("authorization") {
            Some(sent) if same(sent.as_bytes(), expected) => Ok(request),
            sent => {
                self.refused.inc();
                Err(Status::unauthenticated(if sent.is_some() {
                    "the bearer token does not match"
                } else {
                    "planning needs `authorization: Bearer <token>`"
                }))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn call(auth: &mut BearerAuth, header: Option<&str>) -> Result<(), tonic::Code> {
        let mut request = Request::new(());
        if let Some(h) = header {
            request.metadata_mut().insert("authorization", h.parse().unwrap());
        }
        auth.call(request).map(|_| ()).map_err(|s| s.code())
    }

    #[test]
    fn only_the_configured_token_passes() {
        let refused = IntCounter::new("refused", "test").unwrap();
        let mut auth = BearerAuth::new(Some("s3cret".into()), refused.clone());
        assert_eq!(call(&mut auth, Some("Bearer s3cret")), Ok(()));
        for wrong in [
            None,
            Some("Bearer s3cre"),
            Some("Bearer s3cret2"),
            Some("s3cret"),
            Some("Basic s3cret"),
        ] {
            assert_eq!(
                call(&mut auth, wrong),
                Err(tonic::Code::Unauthenticated),
                "{wrong:?}"
            );
        }
        assert_eq!(refused.get(), 5);
        let mut open = BearerAuth::new(None, refused);
        assert_eq!(call(&mut open, None), Ok(()));
    }

    #[test]
    fn token_files_hold_one_word() {
        let dir = std::env::temp_dir().join(format!("mvgrasp-token-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("token");
        let settings = SecuritySettings {
            bearer_token_file: Some(file.clone()),
            ..SecuritySettings::default()
        };
        std::fs::write(&file, "abc123\n").unwrap();
        assert_eq!(load(&settings).unwrap().token.as_deref(), Some("abc123"));
        for bad in ["", "  \n", "two words"] {
            std::fs::write(&file, bad).unwrap();
            assert!(load(&settings).is_err(), "{bad:?}");
        }
        std::fs::remove_file(&file).unwrap();
        let missing = load(&settings).unwrap_err().to_string();
        assert!(missing.contains("security.bearer_token_file"), "{missing}");
    }
}
