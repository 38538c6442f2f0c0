//! Located diagnostics: one catalogue of error names and messages shared by
//! the build script, the macro and the launcher.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::source::{LineCol, SourceFile, Span};

macro_rules! codes {
    ($( $(#[$doc:meta])* $name:ident ),* $(,)?) => {
        /// The name of a diagnostic. Names are stable: users search for them.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[non_exhaustive]
        pub enum Code {
            $( $(#[$doc])* $name, )*
        }

        impl Code {
            /// Every code, in catalogue order.
            pub const ALL: &'static [Code] = &[$( Code::$name, )*];

            /// The name as printed, e.g. `DuplicateLinkId`.
            pub fn as_str(self) -> &'static str {
                match self { $( Code::$name => stringify!($name), )* }
            }
        }
    };
}

codes! {
    /// The file could not be read.
    CannotRead,
    /// The file is larger than peppy documents may be.
    DocumentTooLarge,
    /// JSON5 syntax error.
    Syntax,
    /// Nesting deeper than documents may be.
    NestingTooDeep,
    /// An object has the same key twice.
    DuplicateKey,
    /// A key that this position does not accept.
    UnknownKey,
    /// A required key is absent.
    MissingKey,
    /// A value of the wrong JSON type.
    WrongType,
    /// A value of the right type but outside what is accepted.
    InvalidValue,
    /// `peppy_schema` is missing or names no known document kind.
    UnknownSchema,
    /// A document of another kind where this one was expected.
    WrongDocumentKind,
    /// A name (node, interface, instance, ...) with disallowed characters.
    InvalidName,
    /// A tag that is not a letter-led, dot-free label.
    InvalidTag,
    /// A topic, service or action name that cannot be a key segment.
    InvalidEntryName,
    /// Two entries of one list with the same name.
    DuplicateEntryName,
    /// The same `link_id` declared twice in `depends_on`.
    DuplicateLinkId,
    /// Two `from_any` slots for one `name:tag`.
    ConflictingFromAny,
    /// A consumed entry names a `link_id` that `depends_on` does not declare.
    UndeclaredLinkId,
    /// A consumed service or action without a `link_id`.
    MissingLinkId,
    /// A linked consumed topic that also states a `message_format`.
    LinkedFormatGiven,
    /// An external consumed topic without a `message_format`.
    ExternalFormatMissing,
    /// Both or neither of `run_cmd` / `container`.
    ExecutionConflict,
    /// An empty argv.
    EmptyCommand,
    /// A message format with no fields.
    EmptyMessageFormat,
    /// An unknown primitive type name.
    UnknownType,
    /// A field named `instance_id`.
    ReservedFieldName,
    /// A field name that cannot be a Rust identifier.
    InvalidFieldName,
    /// `$optional` where it is not allowed.
    OptionalMisuse,
    /// `$length` where it is not allowed, or a bad length.
    LengthMisuse,
    /// An array whose items are arrays.
    NestedArray,
    /// `$default` of the wrong type or range, or where defaults are not allowed.
    InvalidDefault,
    /// A service name the runtime reserves.
    ReservedServiceName,
    /// A pairing whose `roles` does not list exactly two roles.
    PairingRoleCount,
    /// A pairing that lists the same role twice.
    DuplicateRole,
    /// A pairing role named `_`, which is reserved as a link key.
    ReservedRole,
    /// A pairing topic `emitted_by` a role the pairing does not declare.
    UnknownRole,
    /// A pairing without topics: it would carry nothing.
    EmptyPairing,
    /// `services` or `actions` in a pairing, which carries topics only.
    PairingTopicsOnly,
    /// A node, interface or launcher that no repository provides.
    DependencyNotFound,
    /// A dependency was found but its document is invalid.
    DependencyInvalid,
    /// A linked entry names a topic, service or action the producer does not offer.
    MissingOnProducer,
    /// A sha256 pin that does not match the interface document.
    InterfacePinMismatch,
    /// The same `conforms_to` entry twice.
    DuplicateConformance,
    /// Two sources define the same topic, service or action name.
    ConflictingDefinition,
    /// The same `name:tag` in two repositories (the first wins).
    DuplicateInRepositories,
    /// One identity claimed by two files of one repository (`repo index`
    /// cannot list both).
    DuplicateIdentity,
    /// A repository-index `path` that is not canonical: empty, absolute,
    /// with a backslash, a `.`, `..` or empty segment, or a trailing `/`.
    NonCanonicalPath,
    /// A repository-index entry whose file is missing, not a file, of
    /// another kind, or declares another identity.
    UnmatchedIndexEntry,
    /// A launcher source that cannot be used.
    InvalidSource,
    /// A launcher source that cannot be had: a git or archive source that
    /// could not be fetched (or checked where nothing fetches).
    UnsupportedSource,
    /// A node whose execution peppy-launch cannot start (a container).
    UnsupportedExecution,
    /// Two deployments of the same `name:tag`.
    DuplicateDeployment,
    /// A deployment without instances.
    EmptyDeployment,
    /// The same `instance_id` twice in a stack.
    DuplicateInstanceId,
    /// A pinned slot without a binding.
    PinnedSlotUnbound,
    /// A binding key that fits no slot.
    DeadBindingKey,
    /// The same binding key twice on one instance.
    DuplicateBindingKey,
    /// The reserved binding key `_`.
    ReservedBindingKey,
    /// A binding names an instance no deployment declares.
    UnknownBindingTarget,
    /// An instance placed on a core node `core_nodes` does not declare.
    UnknownCoreNode,
    /// The same core node twice in `core_nodes`.
    DuplicateCoreNode,
    /// A link target names an instance no deployment declares
    /// (`launcher/v1`; `launcher_v1`'s is `UnknownBindingTarget`).
    UnknownInstanceId,
    /// The reserved link key `_` (`launcher/v1`).
    LinkSentinelKey,
    /// A link target that is not `instance` or `instance/peer_slot`.
    InvalidLinkTarget,
    /// The same target twice in one link's list.
    DuplicateLinkTarget,
    /// A `{ vacant: "<why>" }` link value without a reason.
    InvalidVacancy,
    // Composed launchers (`components`, fragments, adjustments,
    // constraints), named as PeppyOS names them where it does.
    /// `--with` given for a launcher without `components`.
    WithOnFlatLauncher,
    /// A `--with` word, `default` or map naming no axis or option.
    UnknownSelection,
    /// A bare `--with` option word that several axes have.
    AmbiguousSelection,
    /// Two options selected for one axis.
    ConflictingSelection,
    /// A required axis with no default that nothing selects.
    UnresolvedAxis,
    /// A selection a constraint's `requires` does not allow.
    ConstraintUnsatisfied,
    /// A selection a constraint's `forbids` refuses.
    ConstraintForbidden,
    /// A fragment path that is absolute, not plain, or leads outside the
    /// launcher's directory.
    FragmentPath,
    /// A fragment file that does not exist or cannot be read.
    FragmentUnreadable,
    /// A fragment file that does not parse or is not a `launcher_fragment/v1`.
    FragmentInvalid,
    /// An option that does not define an instance its axis `provides`.
    ProvidesUnmet,
    /// An adjustment whose target neither the base nor any option defines.
    TargetDefinedNowhere,
    /// Two fragments writing the same argument or link (or one fragment
    /// appending to a slot it also replaces).
    AdjustmentsConflict,
    /// `add_links` on a slot holding one target or a vacancy.
    AddLinksOnNonArray,
    /// `add_links` adding a target the slot already lists.
    AddLinksDuplicateTarget,
    /// Two axes with one name.
    DuplicateAxis,
    /// The default selection is refused by a constraint (`repo index --check`).
    DefaultSelectionRefused,
    /// More selections than are checked one by one (`repo index --check`).
    TooManySelections,
    /// A constraint that refuses no selection (`repo index --check`).
    ConstraintRefusesNothing,
    /// An option (or an optional axis unfilled) in no legal selection
    /// (`repo index --check`).
    OptionUnreachable,
    /// A node slot bound to an instance of another node.
    BindingTargetMismatch,
    /// An interface slot bound to an instance that does not conform.
    BindingInterfaceNotConformed,
    /// A parameter value of the wrong type or range.
    ParameterTypeMismatch,
    /// A required parameter is missing.
    MissingParameter,
    /// A parameter the schema does not declare.
    UnknownParameter,
    /// An environment variable the launcher refuses to set.
    ForbiddenEnvVar,
    /// A legacy spelling that still works (warning).
    LegacySpelling,
    /// A key that is accepted but has no effect (warning).
    IgnoredKey,
    // `node/v1`'s rules, named as PeppyOS names them.
    /// A malformed `refine` block.
    InvalidRefine,
    /// `refine` on a native entry (one without a `link_id`).
    RefineWithoutLinkId,
    /// Two sibling modules generated for a `node/v1` node (entry names,
    /// link_ids) that read the same once sanitised.
    ModuleNameCollision,
    /// `refine` on an entry consumed through a `depends_on.nodes` slot.
    RefineOnNodeSlot,
    /// An entry with a `link_id` that also states its shape.
    LinkedEntryWithInlineShape,
    /// A produced entry (`link_id`, `name`) listed twice.
    DuplicateInterfaceEntry,
    /// A contract implemented twice by one node.
    DuplicateImplementsContract,
    /// Two `implements` tags that read the same once `-` is `_`.
    ImplementsTagSanitizationCollision,
    /// A produced entry names a link_id no `implements` or pairing slot declares.
    UndeclaredEmitsLinkId,
    /// A produced entry names a `depends_on` slot instead of an `implements` slot.
    EmitsLinkIdNotImplements,
    /// `topics.emits` names a pairing observer slot.
    EmitsOnObserverSlot,
    /// A consumed entry names an `implements` slot.
    ConsumedItemReferencesImplementsLinkId,
    /// A consumed service or action names a pairing slot (pairings are topics-only).
    ConsumedItemReferencesPairingLinkId,
    /// A `cardinality` on a pairing participant slot.
    CardinalityOnPairingSlot,
    /// An `optional` on a pairing observer slot.
    OptionalOnObserverSlot,
    /// A pairing slot without a `role`.
    PairingSlotMissingRole,
    /// A pairing slot link_id that link targets cannot name.
    PairingSentinelLinkId,
    /// A pairing observer slot nothing consumes.
    ObserverLinkNeverConsumed,
    /// An implementer's members differ from the contract's (missing, unknown, duplicated, wrong kind).
    ContractCoverageMismatch,
    /// A `refine` pin that does not land on an open array of scalars.
    RefinementMismatch,
    /// An entry consumed through a node slot that the producer provides only through a contract.
    ConsumedInterfaceOnlyContractBacked,
    /// A pairing slot's topic list differs from its role's (missing, unknown, duplicated, the other role's).
    PairingCoverageMismatch,
    /// A pairing slot pinned to a revision the pairing document no longer has.
    PairingShaMismatch,
    /// A pairing slot naming a role its pairing does not have.
    PairingRoleUnknown,
    /// A pairing link to an instance with no free slot of the counterpart role.
    PairingTargetNotComplementary,
    /// A pairing link to an instance with several complementary slots, without `/slot`.
    PairingTargetAmbiguous,
    /// Both ends of a pair link each other differently.
    PairingConflict,
    /// The two ends of a pair (or an observer and its source) pin different revisions of their pairing.
    PairingSha256Mismatch,
    /// Nodes of a stack calling each other's services or actions round a loop.
    ServiceActionContractCycle,
    /// A pairing slot linked to a second peer.
    PairingSlotAlreadyPaired,
    /// A required participant slot that no link pairs.
    PairingSlotUncovered,
    /// An observer linked to an instance that does not play the watched role.
    ObservationTargetNotObservable,
    /// An observer linked to an instance playing the watched role through several slots, without `/slot`.
    ObservationTargetAmbiguous,
    /// The same source twice in one observer slot.
    DuplicateObservationTarget,
    /// A link key that names no slot of the node.
    LinkUnknownSlot,
    /// `{ vacant }` on a slot that may not stay empty, or that stays empty by omission.
    LinkVacantInvalid,
    /// A required slot (`one`, `one_or_more`, `zero_or_one` not vacated) left out.
    BindingSlotUnfulfilled,
    /// An array of targets on a slot that takes one.
    BindingArrayOnScalarSlot,
    /// A single target on a slot that takes a list.
    BindingScalarOnMultiSlot,
    /// A slot that takes one producer given several.
    BindingSingleSlotMultipleTargets,
    /// An empty list on a `one_or_more` slot.
    BindingCardinalityUnmet,
    /// A contract slot linked to an instance whose node does not implement the contract.
    BindingContractNotImplemented,
    /// The same producer twice in one slot.
    DuplicateBoundProducer,
}

impl fmt::Display for Code {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// How serious a diagnostic is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Severity {
    /// The document is invalid.
    Error,
    /// The document works, but something deserves attention.
    Warning,
}

impl Severity {
    /// `error` or `warning`.
    pub fn as_str(self) -> &'static str {
        match self {
            Severity::Error => "error",
            Severity::Warning => "warning",
        }
    }
}

/// One located finding about a document.
#[derive(Debug, Clone)]
pub struct Diagnostic {
    /// Stable name of the problem.
    pub code: Code,
    /// Error or warning.
    pub severity: Severity,
    /// What was found (lowercase, no trailing period).
    pub message: String,
    /// What would be accepted, or a did-you-mean.
    pub help: Option<String>,
    /// Path of the key in the document, e.g. `interfaces.topics.emits[0].name`.
    pub key_path: Option<String>,
    file: Option<Arc<SourceFile>>,
    file_path: Option<PathBuf>,
    span: Option<Span>,
}

impl Diagnostic {
    /// A new error with no location yet.
    pub fn error(code: Code, message: impl Into<String>) -> Self {
        Diagnostic {
            code,
            severity: Severity::Error,
            message: message.into(),
            help: None,
            key_path: None,
            file: None,
            file_path: None,
            span: None,
        }
    }

    /// A new warning with no location yet.
    pub fn warning(code: Code, message: impl Into<String>) -> Self {
        Diagnostic {
            severity: Severity::Warning,
            ..Diagnostic::error(code, message)
        }
    }

    /// Locates the diagnostic at `span` of `file`.
    pub fn at(mut self, file: &Arc<SourceFile>, span: Span) -> Self {
        self.file_path = Some(file.path().to_path_buf());
        self.file = Some(file.clone());
        self.span = Some(span);
        self
    }

    /// Names the file when no text is available (e.g. it could not be read).
    pub fn with_file_path(mut self, path: &Path) -> Self {
        self.file_path = Some(path.to_path_buf());
        self
    }

    /// Adds what would be accepted.
    pub fn with_help(mut self, help: impl Into<String>) -> Self {
        self.help = Some(help.into());
        self
    }

    /// Sets the key path.
    pub fn with_key_path(mut self, path: impl Into<String>) -> Self {
        let path = path.into();
        self.key_path = (!path.is_empty()).then_some(path);
        self
    }

    /// Whether this is an error (not a warning).
    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }

    /// The file the diagnostic points into, if any.
    pub fn file_path(&self) -> Option<&Path> {
        self.file_path.as_deref()
    }

    /// The source text the diagnostic points into, if loaded.
    pub fn source(&self) -> Option<&Arc<SourceFile>> {
        self.file.as_ref()
    }

    /// The byte span, if located.
    pub fn span(&self) -> Option<Span> {
        self.span
    }

    /// Line and column, if located.
    pub fn line_col(&self) -> Option<LineCol> {
        Some(self.file.as_ref()?.line_col(self.span?.start))
    }

    /// `path:line:col: error: message (Code)`: the line editors jump to.
    ///
    /// `base` makes the path relative when it is inside `base`.
    pub fn jump_line(&self, base: Option<&Path>) -> String {
        let mut out = String::new();
        if let Some(path) = &self.file_path {
            let shown = base.and_then(|b| path.strip_prefix(b).ok()).unwrap_or(path);
            out.push_str(&shown.display().to_string());
            if let Some(lc) = self.line_col() {
                out.push_str(&format!(":{}:{}", lc.line, lc.column));
            }
            out.push_str(": ");
        }
        out.push_str(&format!(
            "{}: {} ({})",
            self.severity.as_str(),
            self.message,
            self.code
        ));
        out
    }

    fn sort_key(&self) -> (Option<PathBuf>, usize, Severity) {
        (
            self.file_path.clone(),
            self.span.map_or(0, |s| s.start),
            self.severity,
        )
    }
}

/// The message alone, as errors display; [`Diagnostic::jump_line`] adds the
/// location and [`Diagnostics`]' `Display` adds help texts.
impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Diagnostic {}

#[cfg(feature = "documents")]
impl miette::SourceCode for SourceFile {
    fn read_span<'a>(
        &'a self,
        span: &miette::SourceSpan,
        context_lines_before: usize,
        context_lines_after: usize,
    ) -> Result<Box<dyn miette::SpanContents<'a> + 'a>, miette::MietteError> {
        let inner = self
            .text()
            .read_span(span, context_lines_before, context_lines_after)?;
        Ok(Box::new(miette::MietteSpanContents::new_named(
            self.path().display().to_string(),
            inner.data(),
            *inner.span(),
            inner.line(),
            inner.column(),
            inner.line_count(),
        )))
    }
}

#[cfg(feature = "documents")]
impl miette::Diagnostic for Diagnostic {
    fn code<'a>(&'a self) -> Option<Box<dyn fmt::Display + 'a>> {
        Some(Box::new(self.code))
    }

    fn severity(&self) -> Option<miette::Severity> {
        Some(match self.severity {
            Severity::Error => miette::Severity::Error,
            Severity::Warning => miette::Severity::Warning,
        })
    }

    fn help<'a>(&'a self) -> Option<Box<dyn fmt::Display + 'a>> {
        self.help
            .as_ref()
            .map(|h| Box::new(h) as Box<dyn fmt::Display>)
    }

    fn source_code(&self) -> Option<&dyn miette::SourceCode> {
        self.file.as_deref().map(|f| f as &dyn miette::SourceCode)
    }

    fn labels(&self) -> Option<Box<dyn Iterator<Item = miette::LabeledSpan> + '_>> {
        let span = self.span?;
        self.file.as_ref()?;
        let label = self.key_path.clone().unwrap_or_else(|| "here".to_string());
        Some(Box::new(std::iter::once(miette::LabeledSpan::new(
            Some(label),
            span.start,
            span.end.saturating_sub(span.start),
        ))))
    }
}

/// Every finding about one or more documents, errors and warnings together.
#[derive(Debug, Clone, Default)]
pub struct Diagnostics {
    items: Vec<Diagnostic>,
}

impl Diagnostics {
    /// No findings.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one finding.
    pub fn push(&mut self, diagnostic: Diagnostic) {
        self.items.push(diagnostic);
    }

    /// Adds all findings of `other`.
    pub fn extend(&mut self, other: Diagnostics) {
        self.items.extend(other.items);
    }

    /// Whether any finding is an error.
    pub fn has_errors(&self) -> bool {
        self.items.iter().any(Diagnostic::is_error)
    }

    /// Whether there are no findings at all.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Number of findings.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// Number of errors.
    pub fn error_count(&self) -> usize {
        self.items.iter().filter(|d| d.is_error()).count()
    }

    /// All findings, sorted by file and position.
    pub fn sorted(&self) -> Vec<&Diagnostic> {
        let mut v: Vec<&Diagnostic> = self.items.iter().collect();
        v.sort_by_key(|d| d.sort_key());
        v
    }

    /// Iterates in insertion order.
    pub fn iter(&self) -> impl Iterator<Item = &Diagnostic> {
        self.items.iter()
    }

    #[cfg(feature = "documents")]
    pub(crate) fn iter_mut(&mut self) -> impl Iterator<Item = &mut Diagnostic> {
        self.items.iter_mut()
    }

    /// The findings that are errors.
    pub fn errors(&self) -> impl Iterator<Item = &Diagnostic> {
        self.items.iter().filter(|d| d.is_error())
    }

    /// Whether some finding has this code.
    pub fn contains(&self, code: Code) -> bool {
        self.items.iter().any(|d| d.code == code)
    }

    /// `Ok(value)` with the warnings when there are no errors, else all findings.
    pub fn into_result<T>(self, value: T) -> Result<(T, Diagnostics), Diagnostics> {
        if self.has_errors() {
            Err(self)
        } else {
            Ok((value, self))
        }
    }
}

impl From<Diagnostic> for Diagnostics {
    fn from(d: Diagnostic) -> Self {
        Diagnostics { items: vec![d] }
    }
}

impl IntoIterator for Diagnostics {
    type Item = Diagnostic;
    type IntoIter = std::vec::IntoIter<Diagnostic>;
    fn into_iter(self) -> Self::IntoIter {
        self.items.into_iter()
    }
}

impl fmt::Display for Diagnostics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, d) in self.sorted().into_iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            f.write_str(&d.jump_line(None))?;
            if let Some(help) = &d.help {
                write!(f, "\n  help: {help}")?;
            }
        }
        Ok(())
    }
}

impl std::error::Error for Diagnostics {}

/// The closest of `candidates` to `found`, when close enough to suggest:
/// at most one edit away (two for longer names), or very similar by
/// Jaro-Winkler.
pub fn did_you_mean<'a>(
    found: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> Option<&'a str> {
    let max_edits = if found.chars().count() >= 6 { 2 } else { 1 };
    candidates
        .into_iter()
        .filter(|c| *c != found)
        .map(|c| {
            (
                strsim::osa_distance(found, c),
                strsim::jaro_winkler(found, c),
                c,
            )
        })
        .filter(|(edits, jw, _)| *edits <= max_edits || *jw > 0.85)
        .min_by(|a, b| a.0.cmp(&b.0).then(b.1.total_cmp(&a.1)))
        .map(|(_, _, c)| c)
}

/// `` `a`, `b`, `c` `` for messages.
pub(crate) fn list<'a>(items: impl IntoIterator<Item = &'a str>) -> String {
    let v: Vec<String> = items.into_iter().map(|s| format!("`{s}`")).collect();
    if v.is_empty() {
        "(none)".to_string()
    } else {
        v.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_code_is_documented() {
        let doc = include_str!("../../docs/DOCUMENTS.md");
        for code in Code::ALL {
            assert!(
                doc.contains(&format!("| `{code}` |")),
                "docs/DOCUMENTS.md does not list `{code}`"
            );
        }
    }
}
