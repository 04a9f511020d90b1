//! What validation reports: problems naming the item and field, as errors or warnings.

use std::fmt;

/// How serious a problem is.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Severity {
    /// The world cannot be built as described.
    Error,
    /// The world can be built, but differs from the description as the message says.
    Warning,
}

/// One thing wrong with a world description, naming the item and the field, as an error or a
/// warning. (The RDF side's validation problems are `tosm::Problem`; the parser turns them into
/// these.)
#[derive(Clone, Debug, PartialEq)]
pub struct SpecProblem {
    /// Error or warning.
    pub severity: Severity,
    /// The item (IRI or identifier) the problem is about.
    pub item: String,
    /// The field or property, for example `size.z` or `tosm:hasRange`.
    pub field: String,
    /// What is wrong, in a full sentence.
    pub message: String,
}

impl SpecProblem {
    /// An error about `item`'s `field`.
    pub fn error(
        item: impl Into<String>,
        field: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Self {
            severity: Severity::Error,
            item: item.into(),
            field: field.into(),
            message: message.into(),
        }
    }

    /// A warning about `item`'s `field`.
    pub fn warning(
        item: impl Into<String>,
        field: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Self {
            severity: Severity::Warning,
            ..Self::error(item, field, message)
        }
    }
}

impl fmt::Display for SpecProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let level = match self.severity {
            Severity::Error => "error",
            Severity::Warning => "warning",
        };
        write!(f, "{level}: {} {}: {}", self.item, self.field, self.message)
    }
}

/// A list of problems; an error type when any of them is an error.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SpecProblems(pub Vec<SpecProblem>);

impl SpecProblems {
    /// Whether any problem is an error.
    pub fn has_errors(&self) -> bool {
        self.0.iter().any(|p| p.severity == Severity::Error)
    }

    /// The errors only.
    pub fn errors(&self) -> impl Iterator<Item = &SpecProblem> {
        self.0.iter().filter(|p| p.severity == Severity::Error)
    }

    /// Whether there are no problems at all.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Adds a problem.
    pub fn push(&mut self, problem: SpecProblem) {
        self.0.push(problem);
    }

    /// `Ok(warnings)` when there is no error, else `Err(self)`.
    pub fn into_result(self) -> Result<Vec<SpecProblem>, SpecProblems> {
        if self.has_errors() {
            Err(self)
        } else {
            Ok(self.0)
        }
    }
}

impl fmt::Display for SpecProblems {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.errors().count();
        write!(f, "{n} error(s), {} warning(s)", self.0.len() - n)?;
        for p in &self.0 {
            write!(f, "\n  {p}")?;
        }
        Ok(())
    }
}

impl std::error::Error for SpecProblems {}
