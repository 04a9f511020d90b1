//! Content negotiation: which serialization answers a request, chosen from its `Accept` header
//! (with q-values and wildcards) and from the `format`/`output`/`results` parameters that
//! SPARQLWrapper adds to every query.

use edge::accept::{parse_accept, quality};
use edge::{ApiError, ErrorCode};
use oxigraph::io::{JsonLdProfileSet, RdfFormat};
use oxigraph::sparql::results::QueryResultsFormat;

/// A serialization the protocols can answer in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// SPARQL query results (SELECT solutions or an ASK boolean).
    Results(QueryResultsFormat),
    /// An RDF graph or dataset.
    Rdf(RdfFormat),
}

/// JSON-LD without profiles: what we serialize and what `application/ld+json` means to us.
pub const JSON_LD: RdfFormat = RdfFormat::JsonLd {
    profile: JsonLdProfileSet::empty(),
};

/// Formats for SELECT solutions and ASK booleans, in the order we prefer them when the client
/// does not mind (JSON first: it is what most clients parse fastest).
pub const RESULT_FORMATS: &[QueryResultsFormat] = &[
    QueryResultsFormat::Json,
    QueryResultsFormat::Xml,
    QueryResultsFormat::Csv,
    QueryResultsFormat::Tsv,
];

/// Formats for one graph (CONSTRUCT, DESCRIBE, a Graph Store graph, the service description).
/// The quad formats are offered too: a graph is a dataset with only a default graph.
pub const GRAPH_FORMATS: &[RdfFormat] = &[
    RdfFormat::Turtle,
    RdfFormat::NTriples,
    RdfFormat::RdfXml,
    JSON_LD,
    RdfFormat::NQuads,
    RdfFormat::TriG,
];

/// Formats for a whole dataset (named graphs included).
pub const DATASET_FORMATS: &[RdfFormat] = &[RdfFormat::TriG, RdfFormat::NQuads, JSON_LD];

/// The `Content-Type` we answer with for `format`.
pub fn content_type(format: Format) -> &'static str {
    match format {
        Format::Results(QueryResultsFormat::Json) => "application/sparql-results+json",
        Format::Results(QueryResultsFormat::Xml) => "application/sparql-results+xml",
        Format::Results(QueryResultsFormat::Csv) => "text/csv; charset=utf-8",
        Format::Results(QueryResultsFormat::Tsv) => "text/tab-separated-values; charset=utf-8",
        Format::Rdf(RdfFormat::Turtle) => "text/turtle; charset=utf-8",
        Format::Rdf(RdfFormat::NTriples) => "application/n-triples",
        Format::Rdf(RdfFormat::NQuads) => "application/n-quads",
        Format::Rdf(RdfFormat::TriG) => "application/trig",
        Format::Rdf(RdfFormat::RdfXml) => "application/rdf+xml",
        Format::Rdf(RdfFormat::JsonLd { .. }) => "application/ld+json",
        Format::Rdf(RdfFormat::N3) => "text/n3; charset=utf-8",
        // Both enums are non-exhaustive; anything new is still named by its library.
        Format::Results(other) => other.media_type(),
        Format::Rdf(other) => other.media_type(),
    }
}

/// The media types a format answers to in `Accept`, canonical first, and the short names
/// SPARQLWrapper-style `format=` parameters use for it.
fn aliases(format: Format) -> (&'static [&'static str], &'static [&'static str]) {
    match format {
        Format::Results(QueryResultsFormat::Json) => (
            &[
                "application/sparql-results+json",
                "application/json",
                "text/javascript",
                "application/javascript",
            ],
            &["json", "srj"],
        ),
        Format::Results(QueryResultsFormat::Xml) => (
            &[
                "application/sparql-results+xml",
                "application/xml",
                "text/xml",
            ],
            &["xml", "srx"],
        ),
        Format::Results(QueryResultsFormat::Csv) => (&["text/csv"], &["csv"]),
        Format::Results(QueryResultsFormat::Tsv) => (&["text/tab-separated-values"], &["tsv"]),
        // A Turtle document is also N3, so clients that ask for N3 (SPARQLWrapper's `N3`) get it.
        Format::Rdf(RdfFormat::Turtle) => (
            &[
                "text/turtle",
                "application/turtle",
                "application/x-turtle",
                "text/n3",
                "text/rdf+n3",
                "application/n3",
            ],
            &["turtle", "ttl", "n3"],
        ),
        Format::Rdf(RdfFormat::NTriples) => {
            (&["application/n-triples"], &["nt", "ntriples", "n-triples"])
        }
        Format::Rdf(RdfFormat::NQuads) => (&["application/n-quads"], &["nq", "nquads", "n-quads"]),
        Format::Rdf(RdfFormat::TriG) => (&["application/trig"], &["trig"]),
        Format::Rdf(RdfFormat::RdfXml) => (
            &["application/rdf+xml", "application/xml", "text/xml"],
            &["rdf", "xml", "rdfxml", "rdf+xml", "rdf/xml"],
        ),
        Format::Rdf(RdfFormat::JsonLd { .. }) => (
            &[
                "application/ld+json",
                "application/x-json+ld",
                "application/json",
            ],
            &["jsonld", "json-ld", "json"],
        ),
        Format::Rdf(RdfFormat::N3) => (&["text/n3"], &["n3"]),
        Format::Results(_) | Format::Rdf(_) => (&[], &[]),
    }
}

/// Picks the format among `offered` (in our order of preference) that answers a request.
///
/// `hints` are the values of `format`/`output`/`results` parameters: the first one that names
/// an offered format (by short name such as `json` or by media type) wins, because
/// SPARQLWrapper sends them on purpose; unknown or empty hints are ignored. Otherwise the
/// `Accept` header decides: the highest q-value wins, ties go to our order, and no header means
/// `*/*`. Nothing acceptable is a 406 naming what we can produce.
pub fn negotiate(
    accept: Option<&str>,
    hints: &[&str],
    offered: &[Format],
    what: &str,
) -> Result<Format, ApiError> {
    for hint in hints {
        let hint = hint.trim().to_ascii_lowercase();
        if hint.is_empty() {
            continue;
        }
        let essence = hint.split(';').next().unwrap_or_default().trim();
        for &format in offered {
            let (media_types, names) = aliases(format);
            if names.contains(&essence) || media_types.contains(&essence) {
                return Ok(format);
            }
        }
    }
    let accept = accept
        .map(str::trim)
        .filter(|a| !a.is_empty())
        .unwrap_or("*/*");
    let ranges = parse_accept(accept);
    let mut best: Option<(Format, f32)> = None;
    for &format in offered {
        let (media_types, _) = aliases(format);
        let q = media_types
            .iter()
            .enumerate()
            .map(|(i, m)| quality(&ranges, m, i > 0))
            .fold(0.0_f32, f32::max);
        if q > 0.0 && best.is_none_or(|(_, best_q)| q > best_q) {
            best = Some((format, q));
        }
    }
    best.map(|(format, _)| format).ok_or_else(|| {
        let available: Vec<&str> = offered
            .iter()
            .map(|&f| content_type(f).split(';').next().unwrap_or_default())
            .collect();
        ApiError::new(
            ErrorCode::NotAcceptable,
            format!(
                "cannot answer {what} in any type of `Accept: {accept}`; available: {}",
                available.join(", ")
            ),
        )
    })
}

/// [`negotiate`] among result formats.
pub fn results_format(
    accept: Option<&str>,
    hints: &[&str],
    what: &str,
) -> Result<QueryResultsFormat, ApiError> {
    let offered: Vec<Format> = RESULT_FORMATS
        .iter()
        .copied()
        .map(Format::Results)
        .collect();
    match negotiate(accept, hints, &offered, what)? {
        Format::Results(format) => Ok(format),
        Format::Rdf(_) => Err(ApiError::internal(
            "results negotiation chose an RDF format",
        )),
    }
}

/// [`negotiate`] among RDF formats; `offered` is usually [`GRAPH_FORMATS`] or
/// [`DATASET_FORMATS`], or a subset for an endpoint that serves fewer.
pub fn rdf_format(
    accept: Option<&str>,
    hints: &[&str],
    offered: &[RdfFormat],
    what: &str,
) -> Result<RdfFormat, ApiError> {
    let offered: Vec<Format> = offered.iter().copied().map(Format::Rdf).collect();
    match negotiate(accept, hints, &offered, what)? {
        Format::Rdf(format) => Ok(format),
        Format::Results(_) => Err(ApiError::internal("RDF negotiation chose a results format")),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // reason: tests
mod tests {
    use super::*;

    fn results(accept: Option<&str>, hints: &[&str]) -> Result<QueryResultsFormat, ErrorCode> {
        results_format(accept, hints, "a SELECT result").map_err(|e| e.code())
    }

    fn graph(accept: Option<&str>, hints: &[&str]) -> Result<RdfFormat, ErrorCode> {
        rdf_format(accept, hints, GRAPH_FORMATS, "a graph").map_err(|e| e.code())
    }

    #[test]
    fn no_accept_or_wildcard_gives_our_first_choice() {
        assert_eq!(results(None, &[]), Ok(QueryResultsFormat::Json));
        assert_eq!(results(Some(""), &[]), Ok(QueryResultsFormat::Json));
        assert_eq!(results(Some("*/*"), &[]), Ok(QueryResultsFormat::Json));
        assert_eq!(graph(None, &[]), Ok(RdfFormat::Turtle));
        assert_eq!(graph(Some("*/*;q=0.1"), &[]), Ok(RdfFormat::Turtle));
    }

    #[test]
    fn exact_types_are_honoured() {
        let cases = [
            ("application/sparql-results+xml", QueryResultsFormat::Xml),
            ("text/csv", QueryResultsFormat::Csv),
            ("text/tab-separated-values", QueryResultsFormat::Tsv),
            ("application/json", QueryResultsFormat::Json),
            (
                "APPLICATION/SPARQL-RESULTS+JSON; charset=utf-8",
                QueryResultsFormat::Json,
            ),
        ];
        for (accept, expected) in cases {
            assert_eq!(results(Some(accept), &[]), Ok(expected), "{accept}");
        }
        let cases = [
            ("text/turtle", RdfFormat::Turtle),
            ("application/n-triples", RdfFormat::NTriples),
            ("application/n-quads", RdfFormat::NQuads),
            ("application/trig", RdfFormat::TriG),
            ("application/rdf+xml", RdfFormat::RdfXml),
            ("application/ld+json", JSON_LD),
            ("text/n3", RdfFormat::Turtle),
        ];
        for (accept, expected) in cases {
            assert_eq!(graph(Some(accept), &[]), Ok(expected), "{accept}");
        }
    }

    #[test]
    fn q_values_rank_and_zero_excludes() {
        assert_eq!(
            results(Some("application/sparql-results+json;q=0.5, text/csv"), &[]),
            Ok(QueryResultsFormat::Csv)
        );
        assert_eq!(
            results(
                Some("application/sparql-results+json;q=0.5, text/csv;q=0.9"),
                &[]
            ),
            Ok(QueryResultsFormat::Csv)
        );
        // The most specific range decides: text/* allows text types, but csv is refused.
        assert_eq!(
            results(Some("text/*, text/csv;q=0"), &[]),
            Ok(QueryResultsFormat::Tsv)
        );
        assert_eq!(
            graph(
                Some("*/*;q=0.1, application/rdf+xml;q=0.8, text/turtle;q=0"),
                &[]
            ),
            Ok(RdfFormat::RdfXml)
        );
        // Equal q: our preference order breaks the tie.
        assert_eq!(
            graph(Some("application/n-triples, text/turtle"), &[]),
            Ok(RdfFormat::Turtle)
        );
    }

    #[test]
    fn browser_accept_header_gets_something() {
        let browser = "text/html,application/xhtml+xml,application/xml;q=0.9,*/*;q=0.8";
        assert_eq!(results(Some(browser), &[]), Ok(QueryResultsFormat::Xml));
        assert_eq!(graph(Some(browser), &[]), Ok(RdfFormat::RdfXml));
    }

    #[test]
    fn nothing_acceptable_is_406_naming_the_alternatives() {
        let err = results_format(Some("text/turtle"), &[], "a SELECT result").unwrap_err();
        assert_eq!(err.code(), ErrorCode::NotAcceptable);
        assert!(
            err.message().contains("application/sparql-results+json"),
            "{}",
            err.message()
        );
        assert!(err.message().contains("text/turtle"), "{}", err.message());
        assert_eq!(
            graph(Some("application/sparql-results+json"), &[]),
            Err(ErrorCode::NotAcceptable)
        );
        assert_eq!(
            results(Some("text/csv;q=0"), &[]),
            Err(ErrorCode::NotAcceptable)
        );
    }

    #[test]
    fn malformed_entries_are_skipped() {
        assert_eq!(
            results(Some("garbage, text/csv"), &[]),
            Ok(QueryResultsFormat::Csv)
        );
        assert_eq!(
            results(Some("text/csv;q=abc, text/tab-separated-values"), &[]),
            Ok(QueryResultsFormat::Tsv)
        );
    }

    #[test]
    fn sparqlwrapper_format_parameters_win() {
        // SPARQLWrapper sends `format=json&output=json&results=json` with a matching Accept.
        assert_eq!(
            results(Some("application/sparql-results+xml"), &["json"]),
            Ok(QueryResultsFormat::Json)
        );
        assert_eq!(
            results(None, &["tsv", "text/tab-separated-values"]),
            Ok(QueryResultsFormat::Tsv)
        );
        assert_eq!(results(None, &["", "csv"]), Ok(QueryResultsFormat::Csv));
        // `json` for a graph means JSON-LD, `xml` means RDF/XML, `n3` gets Turtle.
        assert_eq!(graph(None, &["json"]), Ok(JSON_LD));
        assert_eq!(graph(None, &["xml"]), Ok(RdfFormat::RdfXml));
        assert_eq!(graph(None, &["n3"]), Ok(RdfFormat::Turtle));
        assert_eq!(
            graph(None, &["json-ld", "application/ld+json"]),
            Ok(JSON_LD)
        );
        // Unknown hints fall back to Accept.
        assert_eq!(
            results(Some("text/csv"), &["html"]),
            Ok(QueryResultsFormat::Csv)
        );
        assert_eq!(
            graph(Some("application/n-triples"), &["csv"]),
            Ok(RdfFormat::NTriples)
        );
    }

    #[test]
    fn content_types_are_the_canonical_ones() {
        assert_eq!(
            content_type(Format::Rdf(RdfFormat::Turtle)),
            "text/turtle; charset=utf-8"
        );
        assert_eq!(content_type(Format::Rdf(JSON_LD)), "application/ld+json");
        assert_eq!(
            content_type(Format::Results(QueryResultsFormat::Json)),
            "application/sparql-results+json"
        );
    }
}
