//! Bearer tokens and roles, the same for every service: engineers read and write (the graph,
//! jobs); robots read and use the robot endpoints (on-demand databases, object reports, plans).
//!
//! A request is authenticated once: the guard (`crate::guard`) reads its
//! `Authorization: Bearer <token>` header before the body and keeps the [`Principal`] in the
//! request's extensions; a handler receives it through an extractor — [`Caller`] (any valid
//! token), [`RobotCaller`] (a robot's or an engineer's) or [`EngineerCaller`] — which
//! authenticates itself only on a router served without the guard. [`BearerAuth`] declares
//! the scheme in the services' OpenAPI documents.

use std::collections::HashMap;

use std::sync::Arc;

use crate::error::{ApiError, ErrorCode};
use axum::extract::FromRequestParts;
use axum::http::HeaderMap;
use axum::http::header::AUTHORIZATION;
use axum::http::request::Parts;

/// What a token may do.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Knowledge engineers and operators: read and write everything.
    Engineer,
    /// Robots: read the graph, request on-demand databases and plans, report objects.
    Robot,
}

/// Who presented a token.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Principal {
    /// A name for logs and provenance (e.g. the robot's id).
    pub name: String,
    /// The token's role.
    pub role: Role,
}

/// The configured tokens. With none configured the service is open (tests, local tools).
#[derive(Clone, Default)]
pub struct Tokens {
    by_token: HashMap<String, Principal>,
}

impl std::fmt::Debug for Tokens {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Never print the secrets themselves.
        f.debug_struct("Tokens")
            .field("count", &self.by_token.len())
            .finish()
    }
}

impl Tokens {
    /// No tokens: every request is treated as an engineer's.
    pub fn open() -> Self {
        Self::default()
    }

    /// Adds a token.
    pub fn with(mut self, token: impl Into<String>, name: impl Into<String>, role: Role) -> Self {
        self.by_token.insert(
            token.into(),
            Principal {
                name: name.into(),
                role,
            },
        );
        self
    }

    /// Whether any token is configured.
    pub fn is_open(&self) -> bool {
        self.by_token.is_empty()
    }

    /// The principal behind the request's bearer token. 401 when tokens are configured and
    /// the request has none or an unknown one.
    pub fn authenticate(&self, headers: &HeaderMap) -> Result<Principal, ApiError> {
        if self.is_open() {
            return Ok(Principal {
                name: "anonymous".to_owned(),
                role: Role::Engineer,
            });
        }
        let Some(value) = headers.get(AUTHORIZATION) else {
            return Err(ApiError::new(
                ErrorCode::Unauthorized,
                "missing Authorization header: send `Authorization: Bearer <token>`",
            ));
        };
        let token = value
            .to_str()
            .ok()
            .and_then(|v| {
                v.strip_prefix("Bearer ")
                    .or_else(|| v.strip_prefix("bearer "))
            })
            .map(str::trim)
            .ok_or_else(|| {
                ApiError::new(
                    ErrorCode::Unauthorized,
                    "malformed Authorization header: expected `Bearer <token>`",
                )
            })?;
        self.by_token
            .get(token)
            .cloned()
            .ok_or_else(|| ApiError::new(ErrorCode::Unauthorized, "unknown bearer token"))
    }

    /// Like [`Tokens::authenticate`], and 403 unless the token's role is `role` or engineer.
    pub fn require(&self, headers: &HeaderMap, role: Role) -> Result<Principal, ApiError> {
        self.authenticate(headers)?.require(role)
    }
}

impl Principal {
    /// Itself when its role is `role` or engineer; else 403 naming both roles.
    pub fn require(self, role: Role) -> Result<Principal, ApiError> {
        if self.role == role || self.role == Role::Engineer {
            Ok(self)
        } else {
            Err(ApiError::new(
                ErrorCode::Forbidden,
                format!(
                    "token of {} has role {:?}; this operation needs {:?}",
                    self.name, self.role, role
                ),
            ))
        }
    }
}

/// A route state that knows the tokens, for the caller extractors on routers served without
/// the guard.
pub trait TokenSource {
    /// The configured tokens.
    fn tokens(&self) -> &Tokens;
}

impl<T: TokenSource> TokenSource for Arc<T> {
    fn tokens(&self) -> &Tokens {
        (**self).tokens()
    }
}

/// The request's principal: the one the guard authenticated, else authenticated now (and kept
/// for any later extractor).
fn principal_of<S: TokenSource>(parts: &mut Parts, state: &S) -> Result<Principal, ApiError> {
    if let Some(p) = parts.extensions.get::<Principal>() {
        return Ok(p.clone());
    }
    let p = state.tokens().authenticate(&parts.headers)?;
    parts.extensions.insert(p.clone());
    Ok(p)
}

/// Any caller with a valid token (401 otherwise).
#[derive(Debug, Clone)]
pub struct Caller(pub Principal);

/// A caller with a robot's or an engineer's token (401, or 403 for another role).
#[derive(Debug, Clone)]
pub struct RobotCaller(pub Principal);

/// A caller with an engineer's token (401, or 403 for a robot's).
#[derive(Debug, Clone)]
pub struct EngineerCaller(pub Principal);

impl<S: TokenSource + Send + Sync> FromRequestParts<S> for Caller {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, ApiError> {
        principal_of(parts, state).map(Caller)
    }
}

impl<S: TokenSource + Send + Sync> FromRequestParts<S> for RobotCaller {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, ApiError> {
        principal_of(parts, state)?
            .require(Role::Robot)
            .map(RobotCaller)
    }
}

impl<S: TokenSource + Send + Sync> FromRequestParts<S> for EngineerCaller {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, ApiError> {
        principal_of(parts, state)?
            .require(Role::Engineer)
            .map(EngineerCaller)
    }
}

/// Declares the bearer-token scheme the `security` entries of our OpenAPI documents name.
#[derive(Debug)]
pub struct BearerAuth;

impl utoipa::Modify for BearerAuth {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
        let components = openapi.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "bearer",
            SecurityScheme::Http(HttpBuilder::new().scheme(HttpAuthScheme::Bearer).build()),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn headers(value: &str) -> HeaderMap {
        let mut h = HeaderMap::new();
        h.insert(AUTHORIZATION, value.parse().unwrap());
        h
    }

    #[test]
    fn open_tokens_let_everyone_write() {
        let t = Tokens::open();
        assert_eq!(
            t.require(&HeaderMap::new(), Role::Engineer).unwrap().role,
            Role::Engineer
        );
    }

    #[test]
    fn roles_are_enforced() {
        let t = Tokens::default().with("e1", "alice", Role::Engineer).with(
            "r1",
            "robot-7",
            Role::Robot,
        );
        assert_eq!(
            t.authenticate(&HeaderMap::new()).unwrap_err().code(),
            ErrorCode::Unauthorized
        );
        assert_eq!(
            t.authenticate(&headers("Bearer nope")).unwrap_err().code(),
            ErrorCode::Unauthorized
        );
        assert_eq!(
            t.authenticate(&headers("Basic x")).unwrap_err().code(),
            ErrorCode::Unauthorized
        );
        assert_eq!(
            t.require(&headers("Bearer r1"), Role::Robot).unwrap().name,
            "robot-7"
        );
        assert_eq!(
            t.require(&headers("Bearer e1"), Role::Robot).unwrap().name,
            "alice"
        );
        assert_eq!(
            t.require(&headers("Bearer r1"), Role::Engineer)
                .unwrap_err()
                .code(),
            ErrorCode::Forbidden
        );
    }

    #[test]
    fn debug_output_hides_secrets() {
        let t = Tokens::default().with("s3cret", "alice", Role::Engineer);
        assert!(!format!("{t:?}").contains("s3cret"));
    }
}
