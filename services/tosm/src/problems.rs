//! Validation problems: what is wrong with which individual's which property.

use std::fmt;

/// One thing wrong with the data.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Problem {
    /// The individual's IRI (or `_:id` for a blank node).
    pub individual: String,
    /// The property's IRI (`rdf:type` for problems with the individual's classes).
    pub property: String,
    /// What is wrong, in a sentence.
    pub message: String,
}

impl Problem {
    /// A problem with `individual`'s `property`.
    pub fn new(individual: &str, property: &str, message: impl Into<String>) -> Self {
        Self {
            individual: individual.to_owned(),
            property: property.to_owned(),
            message: message.into(),
        }
    }
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "<{}> <{}>: {}",
            self.individual, self.property, self.message
        )
    }
}

/// Every problem found in one reading or writing, in a stable order.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub struct Problems(pub Vec<Problem>);

impl Problems {
    /// The problems, sorted.
    pub fn iter(&self) -> impl Iterator<Item = &Problem> {
        self.0.iter()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// How many there are.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Sorts and removes duplicates, so that equal data gives equal reports.
    pub(crate) fn normalise(mut self) -> Self {
        self.0.sort();
        self.0.dedup();
        self
    }

    /// `Ok(value)` when there are no problems, `Err(self)` otherwise.
    pub(crate) fn into_result<T>(self, value: T) -> Result<T, Problems> {
        if self.0.is_empty() {
            Ok(value)
        } else {
            Err(self.normalise())
        }
    }
}

impl fmt::Display for Problems {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} problem(s)", self.0.len())?;
        for p in &self.0 {
            write!(f, "\n  {p}")?;
        }
        Ok(())
    }
}

impl std::error::Error for Problems {}

impl IntoIterator for Problems {
    type Item = Problem;
    type IntoIter = std::vec::IntoIter<Problem>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.into_iter()
    }
}
