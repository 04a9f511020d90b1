//! A lexical check of an operation's text before any parser sees it. SPARQL and JSON-LD
//! parsers and the evaluator recurse once per nesting level (a group, a parenthesis, a
//! collection) and once per operator of a chain (a property path `a/b/c`, `!!!x`, `1+1+1`),
//! so a few kilobytes of brackets would overflow a thread's stack and abort the process. The
//! scan is linear, allocates nothing, and refuses such text with a message naming the limit;
//! real queries stay far below both limits.

/// Brackets (`{`, `(`, `[`) open at once, at most.
pub(crate) const MAX_DEPTH: usize = 100;
/// Operators (`!`, `/`, `|`, `^`, `&`, `+`, `-`, `*`, `=`) in one operation, at most.
pub(crate) const MAX_OPERATORS: usize = 2000;

/// What kind of token the scanner is in, to tell a `-` inside a prefixed name (`ex:a-b`) or
/// an exponent (`1e-5`) from an operator.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Token {
    None,
    Variable,
    Name,
    Number,
}

/// Refuses SPARQL text nested deeper than [`MAX_DEPTH`] or with more than [`MAX_OPERATORS`]
/// operators, outside strings, IRIs and comments.
pub(crate) fn check_sparql(text: &str) -> Result<(), String> {
    let b = text.as_bytes();
    let (mut i, mut depth, mut operators) = (0, 0_usize, 0_usize);
    let mut token = Token::None;
    while i < b.len() {
        let c = b[i];
        match c {
            b'#' => {
                while i < b.len() && b[i] != b'\n' {
                    i += 1;
                }
                token = Token::None;
            }
            b'"' | b'\'' => {
                i = skip_string(b, i);
                token = Token::None;
                continue;
            }
            b'<' => {
                if let Some(end) = iri_end(b, i) {
                    i = end + 1;
                    token = Token::None;
                    continue;
                }
                operators += 1;
                token = Token::None;
            }
            b'{' | b'(' | b'[' => {
                depth += 1;
                if depth > MAX_DEPTH {
                    return Err(format!(
                        "the operation nests brackets more than {MAX_DEPTH} deep (at byte {i})"
                    ));
                }
                token = Token::None;
            }
            b'}' | b')' | b']' => {
                depth = depth.saturating_sub(1);
                token = Token::None;
            }
            b'?' | b'$' => token = Token::Variable,
            b'-' => {
                let exponent = token == Token::Number && i > 0 && matches!(b[i - 1], b'e' | b'E');
                if token != Token::Name && !exponent {
                    operators += 1;
                    token = Token::None;
                }
            }
            b'!' | b'/' | b'|' | b'^' | b'&' | b'+' | b'*' | b'=' | b'>' => {
                operators += 1;
                token = Token::None;
            }
            c if (c.is_ascii_alphabetic() || c == b'_' || c == b':') && token == Token::None => {
                token = Token::Name;
            }
            c if c.is_ascii_digit() && token == Token::None => token = Token::Number,
            b'.' if token != Token::Number => token = Token::None,
            // Letters, digits and dots inside a token continue it.
            c if c.is_ascii_alphanumeric() || c == b'_' || c == b':' || c == b'.' => {}
            c if c.is_ascii() => token = Token::None,
            // Non-ASCII bytes belong to names or strings.
            _ => {}
        }
        if operators > MAX_OPERATORS {
            return Err(format!(
                "the operation has more than {MAX_OPERATORS} operators (at byte {i}); split it"
            ));
        }
        i += 1;
    }
    Ok(())
}

/// Whether `keyword` (ASCII, compared case-insensitively) occurs in SPARQL `text` as a word of
/// its own, outside strings, IRIs, comments and prefixed names.
pub(crate) fn has_keyword(text: &str, keyword: &str) -> bool {
    let b = text.as_bytes();
    let word = |c: u8| c.is_ascii_alphanumeric() || c == b'_' || c == b':' || c == b'-';
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'#' => {
                while i < b.len() && b[i] != b'\n' {
                    i += 1;
                }
            }
            b'"' | b'\'' => {
                i = skip_string(b, i);
                continue;
            }
            b'<' => {
                if let Some(end) = iri_end(b, i) {
                    i = end + 1;
                    continue;
                }
            }
            b'?' | b'$' => {
                // A variable's name is no keyword.
                i += 1;
                while i < b.len() && word(b[i]) {
                    i += 1;
                }
                continue;
            }
            c if word(c) => {
                let start = i;
                while i < b.len() && word(b[i]) {
                    i += 1;
                }
                if text[start..i].eq_ignore_ascii_case(keyword) {
                    return true;
                }
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    false
}

/// Refuses JSON (JSON-LD) nested deeper than [`MAX_DEPTH`].
pub(crate) fn check_json(bytes: &[u8]) -> Result<(), String> {
    let (mut i, mut depth) = (0, 0_usize);
    while i < bytes.len() {
        match bytes[i] {
            b'"' => {
                i = skip_string(bytes, i);
                continue;
            }
            b'{' | b'[' => {
                depth += 1;
                if depth > MAX_DEPTH {
                    return Err(format!(
                        "the JSON nests objects and arrays more than {MAX_DEPTH} deep (at byte {i})"
                    ));
                }
            }
            b'}' | b']' => depth = depth.saturating_sub(1),
            _ => {}
        }
        i += 1;
    }
    Ok(())
}

/// The index after the string literal opening at `start` (short or long, with escapes); the
/// end of the text when it never closes (the parser reports that).
fn skip_string(b: &[u8], start: usize) -> usize {
    let quote = b[start];
    let long = b.len() >= start + 3 && b[start + 1] == quote && b[start + 2] == quote;
    let mut i = if long { start + 3 } else { start + 1 };
    while i < b.len() {
        match b[i] {
            b'\\' => i += 2,
            c if c == quote => {
                if !long {
                    return i + 1;
                }
                if b.len() >= i + 3 && b[i + 1] == quote && b[i + 2] == quote {
                    return i + 3;
                }
                i += 1;
            }
            b'\n' if !long => return i + 1,
            _ => i += 1,
        }
    }
    b.len()
}

/// Where the IRI opening at `start` closes, when `<` starts one (`<` is also less-than).
fn iri_end(b: &[u8], start: usize) -> Option<usize> {
    let mut i = start + 1;
    while i < b.len() {
        match b[i] {
            b'>' => return Some(i),
            b'<' | b'"' | b'{' | b'}' | b'|' | b'^' | b'`' | b'\\' => return None,
            c if c.is_ascii_whitespace() => return None,
            _ => i += 1,
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ordinary_queries_pass() {
        for q in [
            "PREFIX tosm: <https://mentalsim.dev/ontology/tosm#>\nSELECT * WHERE { ?p a tosm:Room ; tosm:is-inside/tosm:x ?f . FILTER(?x >= 1e-5 && ?y != \"a{{{((\") } # {{{{",
            "SELECT (COUNT(*) AS ?n) WHERE { { SELECT ?s WHERE { ?s ?p ?o } } OPTIONAL { ?s <http://x/a-b> ?c } }",
            "ASK { ?s ?p '''long ' string with ((((( and \\''' '''}",
        ] {
            assert_eq!(check_sparql(q), Ok(()), "{q}");
        }
    }

    #[test]
    fn deep_nesting_and_operator_chains_are_refused() {
        let groups = format!("SELECT * WHERE {}{}", "{".repeat(500), "}".repeat(500));
        assert!(check_sparql(&groups).unwrap_err().contains("100 deep"));
        let path = format!("SELECT * WHERE {{ ?s {} ?o }}", vec!["<p>"; 3000].join("/"));
        assert!(check_sparql(&path).unwrap_err().contains("operators"));
        let negations = format!("ASK {{ FILTER({}true) }}", "!".repeat(3000));
        assert!(check_sparql(&negations).is_err());
        let minus = format!("ASK {{ FILTER({} 1 > 0) }}", "?a-".repeat(3000));
        assert!(check_sparql(&minus).is_err());
        // Brackets inside strings and IRIs do not count.
        let quoted = format!("ASK {{ ?s ?p \"{}\" }}", "{".repeat(5000));
        assert_eq!(check_sparql(&quoted), Ok(()));
    }

    #[test]
    fn service_is_found_as_a_keyword_only() {
        assert!(has_keyword(
            "SELECT * WHERE { service <http://evil/> { ?s ?p ?o } }",
            "SERVICE"
        ));
        for q in [
            "SELECT * WHERE { ?s ?p \"SERVICE\" }",
            "SELECT * WHERE { ?s <http://x/SERVICE> ?o } # SERVICE",
            "SELECT ?service WHERE { ?s ex:SERVICE ?service }",
        ] {
            assert!(!has_keyword(q, "SERVICE"), "{q}");
        }
    }

    #[test]
    fn json_depth() {
        assert_eq!(
            check_json(br#"{"@context": {"a": "http://x/"}, "a": [1, {"b": "[[["}]}"#),
            Ok(())
        );
        let deep = format!("{}{}", "[".repeat(200), "]".repeat(200));
        assert!(check_json(deep.as_bytes()).is_err());
    }
}
