//! Bearer tokens from configuration, or the generated admin token on first start.

use std::io::Write;
use std::path::Path;

use edge::{Role, Tokens};

use crate::config::Config;

/// The tokens the service accepts. With none configured, reads `<data_dir>/admin.token` or
/// creates it (owner-only permissions) with a fresh random engineer token, and logs its path.
pub fn load(config: &Config) -> Tokens {
    if !config.tokens.is_empty() {
        return config.tokens.iter().fold(Tokens::default(), |tokens, t| {
            tokens.with(t.token.clone(), t.name.clone(), t.role)
        });
    }
    let path = config.admin_token_path();
    match read_or_create(&path) {
        Ok((token, created)) => {
            if created {
                tracing::info!(path = %path.display(), "created the admin token (engineer role)");
                println!("Admin token (engineer role) written to {}", path.display());
            }
            Tokens::default().with(token, "admin", Role::Engineer)
        }
        Err(e) => {
            // The data directory is unusable (readiness reports it). Refuse every token rather
            // than run open: the service must never accept writes without authentication.
            tracing::error!(path = %path.display(), error = %e, "cannot read or create the admin token");
            Tokens::default().with(random_token(), "unreachable-admin", Role::Engineer)
        }
    }
}

fn random_token() -> String {
    format!(
        "{}{}",
        uuid::Uuid::new_v4().simple(),
        uuid::Uuid::new_v4().simple()
    )
}

fn read_or_create(path: &Path) -> std::io::Result<(String, bool)> {
    match std::fs::read_to_string(path) {
        Ok(text) if !text.trim().is_empty() => return Ok((text.trim().to_owned(), false)),
        Ok(_) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => return Err(e),
    }
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)?;
    }
    let token = random_token();
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.mode(0o600);
    }
    let mut file = options.open(path)?;
    file.write_all(token.as_bytes())?;
    file.write_all(b"\n")?;
    file.sync_all()?;
    Ok((token, true))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn admin_token_is_created_once_with_owner_only_permissions() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d/admin.token");
        let (first, created) = read_or_create(&path).unwrap();
        assert!(created);
        assert_eq!(first.len(), 64);
        let (second, created) = read_or_create(&path).unwrap();
        assert!(!created);
        assert_eq!(first, second);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode();
            assert_eq!(mode & 0o777, 0o600);
        }
    }
}
