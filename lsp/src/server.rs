//! The main loop: the protocol's lifecycle (initialize, shutdown, exit), the open
//! documents, and the dispatch of requests and notifications to [`crate::features`].

use crate::docs::{Doc, Docs, PlanState};
use crate::plan::Planner;
use crate::position::LineIndex;
use crate::transport::{self, Frame};
use crossbeam_channel::select;
use lsp_server::{ErrorCode, Message, Notification, Request, RequestId, Response};
use lsp_types::notification::{self as note, Notification as _};
use lsp_types::request::{self as req, Request as _};
use serde_json::Value;
use std::collections::HashMap;
use std::io::{BufRead, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};
use tactus_compiler::imports::Loader;
use tactus_compiler::query::{self, Analysis};
use tactus_compiler::sources::{Origin, SourceMap};

/// How the server works.
#[derive(Clone, Debug)]
pub struct Config {
    /// How long a hover waits for the plan of the version it describes before answering
    /// without ranges, formats and error bounds (default 10 s).
    pub hover_wait: Duration,
    /// Whether profiles that compile get their format plan (default yes; off only in
    /// tests of the protocol, where thousands of variants would each plan).
    pub plans: bool,
    /// The host's loader of imported files on disk (`tactus lsp` passes the command line's,
    /// `tactus_host::catalogue::DiskLoader`); the open documents are read before it. `None`:
    /// imports come from the open documents and Tactus's library only.
    pub disk: Option<fn() -> Box<dyn Loader>>,
    /// Where the library's files are written for the client to open ([`crate::files`]);
    /// `None`: the cache directory.
    pub library_dir: Option<PathBuf>,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            hover_wait: Duration::from_secs(10),
            plans: true,
            disk: None,
            library_dir: None,
        }
    }
}

/// The largest document kept, bytes; a larger one is analysed as empty (with a diagnostic).
pub const MAX_DOCUMENT_BYTES: usize = 16 << 20;

/// How a session ended.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Outcome {
    /// `exit` came after `shutdown` (exit code 0 by the protocol's rule).
    pub clean_exit: bool,
    /// Frames that were not messages (logged, answered with a parse error where owed).
    pub bad_frames: usize,
    /// Messages whose handling panicked (a server bug; logged and answered with an
    /// internal error). Tests require 0.
    pub panics: usize,
    /// Messages handled.
    pub messages: usize,
}

pub(crate) struct Server<'l> {
    out: Box<dyn Write + Send>,
    pub docs: Docs,
    planner: Planner,
    generation: u64,
    log: &'l mut dyn FnMut(&str),
    config: Config,
    initialized: bool,
    shutdown: bool,
    /// The library's directory for the client ([`crate::files::library_dir`]), once asked.
    library: Option<Option<PathBuf>>,
}

/// Serves one client: reads messages from `input`, writes answers to `output`, logs to
/// `log`, until `exit` or the end of the input (the client went away, which ends the
/// session like `exit` without `shutdown`). Never panics on what it reads: bad frames are
/// logged and answered with a parse error where one is owed; a request the server cannot
/// answer gets the protocol's error code.
pub fn serve(
    input: impl BufRead + Send + 'static,
    output: impl Write + Send + 'static,
    config: &Config,
    log: &mut dyn FnMut(&str),
) -> Outcome {
    let (frames_tx, frames) = crossbeam_channel::bounded::<Frame>(16);
    let mut input = input;
    let reader = std::thread::Builder::new()
        .name("tactus-lsp-reader".into())
        .spawn(move || loop {
            let f = transport::read_frame(&mut input);
            let end = matches!(f, Frame::End);
            if frames_tx.send(f).is_err() || end {
                return;
            }
        });
    let mut outcome = Outcome::default();
    if reader.is_err() {
        log("cannot start the reader thread");
        return outcome;
    }
    let mut server = Server {
        out: Box::new(output),
        docs: HashMap::new(),
        planner: Planner::start(),
        generation: 0,
        log,
        config: config.clone(),
        initialized: false,
        shutdown: false,
        library: None,
    };
    let done = server.planner.done.clone();
    loop {
        select! {
            recv(frames) -> f => {
                let f = f.unwrap_or(Frame::End);
                match f {
                    Frame::End => {
                        if !server.shutdown {
                            (server.log)("the client went away: ending the session");
                        }
                        return outcome;
                    }
                    Frame::Bad { why, reply } => {
                        outcome.bad_frames += 1;
                        (server.log)(&format!("dropped a bad frame: {why}"));
                        if let Some(r) = reply {
                            server.write_raw(&r);
                        }
                    }
                    Frame::Message(m) => {
                        outcome.messages += 1;
                        let is_exit = matches!(&m, Message::Notification(n) if n.method == note::Exit::METHOD);
                        if is_exit {
                            outcome.clean_exit = server.shutdown;
                            return outcome;
                        }
                        let id = match &m { Message::Request(r) => Some(r.id.clone()), _ => None };
                        let handled = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| server.handle(m)));
                        if handled.is_err() {
                            outcome.panics += 1;
                            (server.log)("internal error: a handler panicked");
                            if let Some(id) = id {
                                server.send(Response::new_err(id, ErrorCode::InternalError as i32, "internal error".into()).into());
                            }
                        }
                    }
                }
            }
            recv(done) -> d => {
                if let Ok(d) = d {
                    server.plan_done(d);
                }
            }
        }
    }
}

fn to_json(m: &Message) -> Value {
    let mut v = serde_json::to_value(m).unwrap_or(Value::Null);
    if let Value::Object(o) = &mut v {
        o.insert("jsonrpc".into(), "2.0".into());
    }
    v
}

impl Server<'_> {
    fn write_raw(&mut self, v: &Value) {
        if let Err(e) = transport::write_message(&mut self.out, v) {
            (self.log)(&format!("cannot write to the client: {e}"));
        }
    }

    pub(crate) fn send(&mut self, m: Message) {
        self.write_raw(&to_json(&m));
    }

    fn reply<R: serde::Serialize>(&mut self, id: RequestId, result: R) {
        self.send(Response::new_ok(id, result).into());
    }

    fn error(&mut self, id: RequestId, code: ErrorCode, message: String) {
        self.send(Response::new_err(id, code as i32, message).into());
    }

    fn handle(&mut self, m: Message) {
        match m {
            Message::Request(r) => self.request(r),
            Message::Notification(n) => self.notification(n),
            Message::Response(_) => {} // we send no requests
        }
    }

    fn request(&mut self, r: Request) {
        if r.method == req::Initialize::METHOD {
            if self.initialized {
                return self.error(
                    r.id,
                    ErrorCode::InvalidRequest,
                    "initialize was already sent".into(),
                );
            }
            self.initialized = true;
            return self.reply(r.id, crate::features::initialize_result());
        }
        if !self.initialized {
            return self.error(
                r.id,
                ErrorCode::ServerNotInitialized,
                format!("`{}` before initialize", r.method),
            );
        }
        if self.shutdown {
            return self.error(
                r.id,
                ErrorCode::InvalidRequest,
                format!("`{}` after shutdown", r.method),
            );
        }
        let id = r.id.clone();
        let result: Result<Value, (ErrorCode, String)> = match r.method.as_str() {
            req::Shutdown::METHOD => {
                self.shutdown = true;
                Ok(Value::Null)
            }
            req::HoverRequest::METHOD => params::<req::HoverRequest>(r).map(|p| {
                // A hover shows the plan of the version it describes, if it comes soon.
                let uri = &p.text_document_position_params.text_document.uri;
                self.wait_for_plan(uri.as_str());
                to_value(crate::features::hover(&self.docs, p))
            }),
            req::GotoDefinition::METHOD => params::<req::GotoDefinition>(r).map(|p| {
                let uri = p.text_document_position_params.text_document.uri.as_str();
                let lib = self.library_dir_of(uri);
                to_value(crate::features::definition(&self.docs, lib.as_deref(), p))
            }),
            req::References::METHOD => params::<req::References>(r).map(|p| {
                let lib = self.library_dir_of(p.text_document_position.text_document.uri.as_str());
                to_value(crate::features::references(&self.docs, lib.as_deref(), p))
            }),
            req::Completion::METHOD => params::<req::Completion>(r)
                .map(|p| to_value(crate::features::completion(&self.docs, p))),
            req::DocumentSymbolRequest::METHOD => params::<req::DocumentSymbolRequest>(r)
                .map(|p| to_value(crate::features::document_symbols(&self.docs, p))),
            other => Err((
                ErrorCode::MethodNotFound,
                format!("`{other}` is not supported"),
            )),
        };
        match result {
            Ok(v) => self.reply(id, v),
            Err((code, msg)) => {
                (self.log)(&format!("request {id}: {msg}"));
                self.error(id, code, msg)
            }
        }
    }

    fn notification(&mut self, n: Notification) {
        if !self.initialized {
            return; // dropped before initialize (the protocol's rule)
        }
        let r = match n.method.as_str() {
            note::DidOpenTextDocument::METHOD => {
                note_params::<note::DidOpenTextDocument>(n).map(|p| {
                    let d = p.text_document;
                    self.set_text(d.uri, d.version, d.text);
                })
            }
            note::DidChangeTextDocument::METHOD => note_params::<note::DidChangeTextDocument>(n)
                .map(|p| {
                    let key = p.text_document.uri.as_str().to_string();
                    let Some(doc) = self.docs.get(&key) else {
                        (self.log)(&format!("didChange of {key}, which is not open: dropped"));
                        return;
                    };
                    let mut text = doc.text.clone();
                    for c in p.content_changes {
                        match c.range {
                            None => text = c.text,
                            Some(range) => {
                                let li = LineIndex::new(&text);
                                let a = li.offset(&text, range.start);
                                let b = li.offset(&text, range.end).max(a);
                                text.replace_range(a..b, &c.text);
                            }
                        }
                    }
                    self.set_text(p.text_document.uri, p.text_document.version, text);
                }),
            note::DidCloseTextDocument::METHOD => {
                note_params::<note::DidCloseTextDocument>(n).map(|p| {
                    if let Some(doc) = self.docs.remove(p.text_document.uri.as_str()) {
                        self.publish(&doc.uri, Vec::new(), None);
                    }
                })
            }
            _ => Ok(()), // didSave, $/cancelRequest, initialized, …: nothing to do
        };
        if let Err((_, msg)) = r {
            (self.log)(&format!("dropped a notification: {msg}"));
        }
    }

    /// The directory of the library's files for the client, written on first use.
    pub(crate) fn library_dir(&mut self) -> Option<PathBuf> {
        if self.library.is_none() {
            let dir = crate::files::library_dir(self.config.library_dir.as_deref());
            if dir.is_none() {
                (self.log)("cannot write the library's files: definitions in it are not shown");
            }
            self.library = Some(dir);
        }
        self.library.clone().flatten()
    }

    /// [`Server::library_dir`] when `sources` hold a library file (none is written for a
    /// program that imports nothing from it).
    /// Where Tactus's library is written for the open document `uri`, if it imports from it.
    fn library_dir_of(&mut self, uri: &str) -> Option<PathBuf> {
        let sources = self.docs.get(uri)?.analysis.sources.clone();
        self.library_dir_for(&sources)
    }

    pub(crate) fn library_dir_for(&mut self, sources: &SourceMap) -> Option<PathBuf> {
        let uses = sources
            .files()
            .iter()
            .any(|f| matches!(f.origin, Origin::Library(_)));
        uses.then(|| self.library_dir()).flatten()
    }

    /// Analyses a document's new text, publishes its diagnostics and asks for its plan; then
    /// analyses again the open documents that import it.
    fn set_text(&mut self, uri: lsp_types::Uri, version: i32, text: String) {
        let key = uri.as_str().to_string();
        self.analyse(uri, version, text);
        let path = self.docs.get(&key).and_then(|d| d.path.clone());
        let Some(path) = path.map(|p| std::fs::canonicalize(&p).unwrap_or(p)) else {
            return;
        };
        let dependents: Vec<(lsp_types::Uri, i32, String)> = self
            .docs
            .iter()
            .filter(|(k, d)| {
                **k != key
                    && d.analysis.sources.files()[1..]
                        .iter()
                        .any(|f| f.origin == Origin::File(path.clone()))
            })
            .map(|(_, d)| (d.uri.clone(), d.version, d.text.clone()))
            .collect();
        for (uri, version, text) in dependents {
            self.analyse(uri, version, text);
        }
    }

    fn analyse(&mut self, uri: lsp_types::Uri, version: i32, text: String) {
        let key = uri.as_str().to_string();
        let path = crate::files::uri_to_path(&key);
        let mut analysis = if text.len() > MAX_DOCUMENT_BYTES {
            Analysis {
                diagnostics: vec![tactus_compiler::diagnostics::Diagnostic::error(
                    "E0000",
                    format!("this file is {} bytes; the language server reads at most {MAX_DOCUMENT_BYTES}", text.len()),
                    0..0,
                )],
                lowered: None,
                outline: Vec::new(),
                names: Default::default(),
                imported: Vec::new(),
                sources: SourceMap::new(key.clone(), Origin::Text, ""),
            }
        } else {
            let open: HashMap<PathBuf, &str> = self
                .docs
                .iter()
                .filter(|(k, _)| **k != key)
                .filter_map(|(_, d)| Some((d.path.clone()?, d.text.as_str())))
                .collect();
            let mut loader = crate::files::Overlay {
                open: &open,
                disk: self.config.disk.map(|f| f()),
            };
            let (name, origin) = match &path {
                Some(p) => (
                    p.display().to_string(),
                    Origin::File(std::fs::canonicalize(p).unwrap_or_else(|_| p.clone())),
                ),
                None => (key.clone(), Origin::Text),
            };
            let linked = tactus_compiler::imports::link(&name, origin, &text, &mut loader);
            query::analyse_linked(&linked, &tactus_compiler::lower::Config::default())
        };
        // A file of components only is a library being edited: "no instrument" says nothing.
        let library = !analysis.outline.is_empty()
            && analysis
                .outline
                .iter()
                .all(|s| s.kind == query::SymbolKind::Component);
        if library {
            analysis.diagnostics.retain(|d| d.code != "E0103");
        }
        let last_outline = match (analysis.outline.is_empty(), self.docs.remove(&key)) {
            (true, Some(old)) => old.last_outline,
            _ => analysis.outline.clone(),
        };
        self.generation += 1;
        let plan = match analysis.lowered.as_mut() {
            Some(l) if self.config.plans => {
                self.planner
                    .request(&key, self.generation, l.program.clone());
                PlanState::Pending(self.generation)
            }
            _ => PlanState::None,
        };
        let lines = LineIndex::new(&text);
        let lib = self.library_dir_for(&analysis.sources);
        let diagnostics = crate::features::diagnostics(
            &uri,
            &analysis.sources,
            lib.as_deref(),
            &analysis.diagnostics,
        );
        self.publish(&uri, diagnostics, Some(version));
        self.docs.insert(
            key,
            Doc {
                uri,
                path,
                version,
                text,
                lines,
                analysis,
                last_outline,
                plan,
            },
        );
    }

    fn publish(
        &mut self,
        uri: &lsp_types::Uri,
        diagnostics: Vec<lsp_types::Diagnostic>,
        version: Option<i32>,
    ) {
        let p = lsp_types::PublishDiagnosticsParams {
            uri: uri.clone(),
            diagnostics,
            version,
        };
        self.send(Notification::new(note::PublishDiagnostics::METHOD.into(), p).into());
    }

    fn plan_done(&mut self, (uri, generation, planned): crate::plan::Done) {
        let Some(doc) = self.docs.get_mut(&uri) else {
            return;
        };
        if !matches!(doc.plan, PlanState::Pending(g) if g == generation) {
            return; // an older version's
        }
        doc.plan = match planned {
            Ok(p) => PlanState::Ready(p),
            Err(e) => {
                (self.log)(&format!("{uri}: {e}"));
                PlanState::Failed(e)
            }
        };
    }

    /// Waits (at most [`Config::hover_wait`]) for the plan of document `key`'s current version.
    pub(crate) fn wait_for_plan(&mut self, key: &str) {
        let deadline = Instant::now() + self.config.hover_wait;
        while matches!(
            self.docs.get(key).map(|d| &d.plan),
            Some(PlanState::Pending(_))
        ) {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.planner.done.recv_timeout(left) {
                Ok(d) => self.plan_done(d),
                Err(_) => return,
            }
        }
    }
}

fn params<R: req::Request>(r: Request) -> Result<R::Params, (ErrorCode, String)> {
    serde_json::from_value(r.params).map_err(|e| {
        (
            ErrorCode::InvalidParams,
            format!("`{}`: bad params: {e}", r.method),
        )
    })
}

fn note_params<N: note::Notification>(n: Notification) -> Result<N::Params, (ErrorCode, String)> {
    serde_json::from_value(n.params).map_err(|e| {
        (
            ErrorCode::InvalidParams,
            format!("`{}`: bad params: {e}", n.method),
        )
    })
}

fn to_value<T: serde::Serialize>(t: T) -> Value {
    serde_json::to_value(t).unwrap_or(Value::Null)
}
