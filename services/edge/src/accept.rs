//! `Accept` headers: media ranges with q-values and wildcards, and which of the media types a
//! service offers a request takes. The SPARQL protocols (`knowledge`) and the plan endpoint
//! (`api`) negotiate through these.

use crate::{ApiError, ErrorCode};

/// One entry of an `Accept` header.
#[derive(Debug, Clone, PartialEq)]
pub struct MediaRange {
    /// The type (`*` for any), lower-case.
    pub kind: String,
    /// The subtype (`*` for any), lower-case.
    pub subtype: String,
    /// The q-value, in `[0, 1]`.
    pub q: f32,
}

impl MediaRange {
    /// How specifically this range names `kind/subtype`: 3 exact, 2 `kind/*`, 1 `*/*`, 0 not.
    pub fn specificity(&self, kind: &str, subtype: &str) -> u8 {
        if self.kind == "*" {
            1
        } else if self.kind != kind {
            0
        } else if self.subtype == "*" {
            2
        } else if self.subtype == subtype {
            3
        } else {
            0
        }
    }
}

/// Parses an `Accept` header. Malformed entries are skipped rather than failing the request:
/// a client with one odd entry should still get an answer from the others.
pub fn parse_accept(header: &str) -> Vec<MediaRange> {
    header
        .split(',')
        .filter_map(|entry| {
            let mut parts = entry.split(';');
            let (kind, subtype) = parts.next()?.trim().split_once('/')?;
            let (kind, subtype) = (kind.trim(), subtype.trim());
            if kind.is_empty() || subtype.is_empty() || (kind == "*" && subtype != "*") {
                return None;
            }
            let mut q = 1.0;
            for parameter in parts {
                if let Some((name, value)) = parameter.split_once('=')
                    && name.trim().eq_ignore_ascii_case("q")
                {
                    q = value.trim().parse::<f32>().ok()?.clamp(0.0, 1.0);
                }
            }
            Some(MediaRange {
                kind: kind.to_ascii_lowercase(),
                subtype: subtype.to_ascii_lowercase(),
                q,
            })
        })
        .collect()
}

/// The q-value `ranges` give to `media_type`: that of the most specific matching range, 0 when
/// none matches. With `exact_only`, wildcards do not count: aliases (say `text/xml` for SPARQL
/// XML results) are matched only when named, so `text/*` does not earn an `application/…` answer.
pub fn quality(ranges: &[MediaRange], media_type: &str, exact_only: bool) -> f32 {
    let Some((kind, subtype)) = media_type.split_once('/') else {
        return 0.0;
    };
    let mut best: (u8, f32) = (0, 0.0);
    for range in ranges {
        let specificity = range.specificity(kind, subtype);
        if exact_only && specificity < 3 {
            continue;
        }
        if specificity > best.0 || (specificity == best.0 && specificity > 0 && range.q > best.1) {
            best = (specificity, range.q);
        }
    }
    best.1
}

/// The media type among `offered` (in the service's order of preference) that answers a
/// request with this `Accept` header (none or an empty one means `*/*`): the highest q-value;
/// at equal q the one the header names more specifically (`application/x-mcap` over `*/*`),
/// then the service's order. Nothing acceptable is a 406 naming `what` and what is offered.
pub fn choose<'a>(
    accept: Option<&str>,
    offered: &[&'a str],
    what: &str,
) -> Result<&'a str, ApiError> {
    let header = accept.map(str::trim).filter(|a| !a.is_empty());
    let ranges = parse_accept(header.unwrap_or("*/*"));
    let mut best: Option<(&str, f32, u8)> = None;
    for &media_type in offered {
        let Some((kind, subtype)) = media_type.split_once('/') else {
            continue;
        };
        let q = quality(&ranges, media_type, false);
        let specificity = ranges
            .iter()
            .map(|r| r.specificity(kind, subtype))
            .max()
            .unwrap_or(0);
        if q > 0.0 && best.is_none_or(|(_, bq, bs)| q > bq || (q == bq && specificity > bs)) {
            best = Some((media_type, q, specificity));
        }
    }
    best.map(|(m, _, _)| m).ok_or_else(|| {
        ApiError::new(
            ErrorCode::NotAcceptable,
            format!(
                "{what} answers {}; the request accepts {:?}",
                offered.join(" or "),
                header.unwrap_or("")
            ),
        )
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // reason: tests
mod tests {
    use super::*;

    const OFFERED: &[&str] = &["application/json", "application/x-mcap"];

    fn pick(accept: Option<&str>) -> Option<&'static str> {
        choose(accept, OFFERED, "POST /v1/plan").ok()
    }

    #[test]
    fn the_first_offer_answers_no_header_and_wildcards() {
        assert_eq!(pick(None), Some("application/json"));
        assert_eq!(pick(Some("")), Some("application/json"));
        assert_eq!(pick(Some("*/*")), Some("application/json"));
        assert_eq!(pick(Some("application/*")), Some("application/json"));
    }

    #[test]
    fn a_named_type_beats_a_wildcard_at_equal_q_and_q_decides_first() {
        assert_eq!(pick(Some("application/x-mcap")), Some("application/x-mcap"));
        assert_eq!(
            pick(Some("application/x-mcap, */*")),
            Some("application/x-mcap")
        );
        assert_eq!(
            pick(Some("application/json;q=0.5, application/x-mcap")),
            Some("application/x-mcap")
        );
        assert_eq!(
            pick(Some("application/json, application/x-mcap;q=0.9")),
            Some("application/json")
        );
        assert_eq!(
            pick(Some("*/*, application/json;q=0")),
            Some("application/x-mcap")
        );
    }

    #[test]
    fn nothing_acceptable_is_406_naming_the_offers() {
        let e = choose(Some("text/html"), OFFERED, "POST /v1/plan").unwrap_err();
        assert_eq!(e.code(), ErrorCode::NotAcceptable);
        assert!(
            e.message()
                .contains("application/json or application/x-mcap"),
            "{}",
            e.message()
        );
        assert!(e.message().contains("text/html"));
    }
}
