//! TLS, mutual TLS and the bearer token, end to end with certificates made
//! here (rcgen): who gets to plan, and that probes still reach health.

use std::path::{Path, PathBuf};

use mvgrasp_client::{Credentials, Error, PlannerClient};
use mvgrasp_server::BackendKind;
use nalgebra::Vector3;
use rcgen::{BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair};
use tonic::Code;
use tonic_health::pb::health_check_response::ServingStatus;

use crate::{
    fixture::{request, sample, scrape, settings, start},
    scene::{Camera, grid_scene},
};

fn frame() -> mvgrasp_client::pb::PlanGraspsRequest {
    request(
        &grid_scene(0.0, 4, 2, 0.13),
        &Camera::orbit(Vector3::zeros(), 0.85, 50.0, -90.0),
    )
}

/// A CA that signs server and client certificates, written as PEM files.
struct Authority {
    issuer: Issuer<'static, KeyPair>,
    cert_pem: String,
    dir: PathBuf,
}

impl Authority {
    fn new(dir: &Path, name: &str) -> Self {
        let mut params = CertificateParams::new(Vec::<String>::new()).unwrap();
        params.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
        params.distinguished_name.push(DnType::CommonName, name);
        let key = KeyPair::generate().unwrap();
        let cert_pem = params.self_signed(&key).unwrap().pem();
        std::fs::create_dir_all(dir).unwrap();
        std::fs::write(dir.join(format!("{name}.crt")), &cert_pem).unwrap();
        Self {
            issuer: Issuer::new(params, key),
            cert_pem,
            dir: dir.to_owned(),
        }
    }

    /// (certificate file, key file) for `names`, for a server or a client.
    fn sign(&self, file: &str, names: &[&str], usage: ExtendedKeyUsagePurpose) -> (PathBuf, PathBuf) {
        let mut params =
            CertificateParams::new(names.iter().map(|n| n.to_string()).collect::<Vec<_>>()).unwrap();
        params.extended_key_usages = vec![usage];
        let key = KeyPair::generate().unwrap();
        let cert = params.signed_by(&key, &self.issuer).unwrap();
        let (c, k) = (
            self.dir.join(format!("{file}.crt")),
            self.dir.join(format!("{file}.key")),
        );
        std::fs::write(&c, cert.pem()).unwrap();
        std::fs::write(&k, key.serialize_pem()).unwrap();
        (c, k)
    }
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mvgrasp-security-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Plans once with `credentials`; the error, if connecting or the call failed.
async fn plan_with(address: &str, credentials: &Credentials) -> Result<usize, Error> {
    let mut client = PlannerClient::connect_with(address, credentials).await?;
    Ok(client.plan(frame()).await?.objects.len())
}

fn identity(files: &(PathBuf, PathBuf)) -> Option<(Vec<u8>, Vec<u8>)> {
    Some((std::fs::read(&files.0).unwrap(), std::fs::read(&files.1).unwrap()))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tls_and_mutual_tls_decide_who_plans() {
    let dir = scratch("tls");
    let ca = Authority::new(&dir, "fleet-ca");
    let stranger_ca = Authority::new(&dir.join("other"), "stranger-ca");
    let server_files = ca.sign(
        "server",
        &["localhost", "127.0.0.1"],
        ExtendedKeyUsagePurpose::ServerAuth,
    );
    let robot = ca.sign("robot", &["robot-1"], ExtendedKeyUsagePurpose::ClientAuth);
    let stranger = stranger_ca.sign("stranger", &["robot-1"], ExtendedKeyUsagePurpose::ClientAuth);
    let trusting = Credentials {
        tls_ca_pem: Some(ca.cert_pem.clone().into_bytes()),
        ..Credentials::default()
    };

    // TLS: a client that trusts the CA plans; one speaking plaintext does not.
    let mut s = settings(BackendKind::Baseline);
    s.security.tls_cert = Some(server_files.0.clone());
    s.security.tls_key = Some(server_files.1.clone());
    let (tls_server, _) = (mvgrasp_server::start(s.clone()).await.unwrap(), ());
    let address = format!("http://127.0.0.1:{}", tls_server.addr.port());
    assert_eq!(plan_with(&address, &trusting).await.unwrap(), 4);
    assert!(
        plan_with(&address, &Credentials::default()).await.is_err(),
        "plaintext to a TLS port"
    );
    let wrong_ca = Credentials {
        tls_ca_pem: Some(stranger_ca.cert_pem.clone().into_bytes()),
        ..Credentials::default()
    };
    assert!(
        plan_with(&address, &wrong_ca).await.is_err(),
        "a server the client does not trust"
    );
    tls_server.shutdown().await.unwrap();

    // Mutual TLS: only a client certificate from the fleet's CA gets in; the
    // plaintext health port answers probes all the same.
    s.security.tls_client_ca = Some(dir.join("fleet-ca.crt"));
    s.security.health_listen = Some("127.0.0.1:0".parse().unwrap());
    let mtls_server = mvgrasp_server::start(s).await.unwrap();
    let address = format!("http://127.0.0.1:{}", mtls_server.addr.port());
    let err = plan_with(&address, &trusting).await.unwrap_err();
    eprintln!("no client certificate: {err}");
    let outsider = Credentials {
        tls_identity_pem: identity(&stranger),
        ..trusting.clone()
    };
    assert!(
        plan_with(&address, &outsider).await.is_err(),
        "a certificate from another CA"
    );
    let member = Credentials {
        tls_identity_pem: identity(&robot),
        ..trusting.clone()
    };
    assert_eq!(plan_with(&address, &member).await.unwrap(), 4);
    let health = format!("http://{}", mtls_server.health_addr.unwrap());
    let mut probe = PlannerClient::connect(&health).await.unwrap();
    assert_eq!(probe.health().await.unwrap(), ServingStatus::Serving);
    assert!(
        probe.plan(frame()).await.is_err(),
        "the health port plans nothing"
    );
    mtls_server.shutdown().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_bearer_token_guards_planning_not_health_or_metrics() {
    let dir = scratch("token");
    let token_file = dir.join("token");
    std::fs::write(&token_file, "fleet-7f3a9c\n").unwrap();
    let mut s = settings(BackendKind::Baseline);
    s.security.bearer_token_file = Some(token_file);
    let (server, mut anonymous) = start(s).await;
    let address = format!("http://{}", server.addr);

    let refused = anonymous.plan(frame()).await.unwrap_err();
    assert!(
        matches!(&refused, Error::Rpc(s) if s.code() == Code::Unauthenticated),
        "{refused}"
    );
    assert_eq!(anonymous.health().await.unwrap(), ServingStatus::Serving);
    let wrong = Credentials {
        bearer_token: Some("fleet-7f3a9d".into()),
        ..Credentials::default()
    };
    let refused = plan_with(&address, &wrong).await.unwrap_err();
    assert!(
        matches!(&refused, Error::Rpc(s) if s.code() == Code::Unauthenticated),
        "{refused}"
    );
    let right = Credentials {
        bearer_token: Some("fleet-7f3a9c".into()),
        ..Credentials::default()
    };
    assert_eq!(plan_with(&address, &right).await.unwrap(), 4);
    // The stream is guarded too.
    let mut client = PlannerClient::connect_with(&address, &right).await.unwrap();
    let mut answers = client.stream(tokio_stream::iter(vec![frame()])).await.unwrap();
    assert_eq!(answers.message().await.unwrap().unwrap().objects.len(), 4);
    assert!(anonymous.stream(tokio_stream::iter(vec![frame()])).await.is_err());

    let metrics = scrape(server.metrics_addr.unwrap()).await;
    assert_eq!(sample(&metrics, "mvgrasp_unauthenticated_calls_total"), 3.0);
    server.shutdown().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}
