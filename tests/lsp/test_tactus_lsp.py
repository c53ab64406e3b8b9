"""End-to-end: `tactus lsp` driven by a real LSP client (pytest-lsp, on pygls).

Run by `tests/lsp_client.rs` (`cargo test --test lsp_client`), which passes the binary in
TACTUS_BIN; by hand: `TACTUS_BIN=target/debug/tactus python3 -m pytest tests/lsp`.
"""

import os
import pathlib
import sys
import urllib.parse

import pytest
import pytest_lsp
from lsprotocol import types
from pytest_lsp import ClientServerConfig, LanguageClient

ROOT = pathlib.Path(__file__).resolve().parents[2]
TACTUS = os.environ.get("TACTUS_BIN", str(ROOT / "target" / "debug" / "tactus"))
HARPSICHORD = (ROOT / "instruments" / "harpsichord.tactus").read_text()
URI = (ROOT / "target" / "lsp-e2e" / "harpsichord.tactus").as_uri()
# Where the server writes the library's files for go-to-definition (its cache directory).
CACHE = ROOT / "target" / "lsp-e2e" / "cache"


@pytest_lsp.fixture(
    config=ClientServerConfig(
        server_command=[TACTUS, "lsp", "--stdio"],
        server_env={**os.environ, "TACTUS_CACHE_DIR": str(CACHE)},
    )
)
async def client(lsp_client: LanguageClient):
    await lsp_client.initialize_session(
        types.InitializeParams(capabilities=types.ClientCapabilities())
    )
    yield
    await lsp_client.shutdown_session()


def position(text: str, needle: str, delta: int = 0) -> types.Position:
    at = text.index(needle) + delta
    line = text.count("\n", 0, at)
    return types.Position(line=line, character=at - (text.rfind("\n", 0, at) + 1))


def open_doc(client: LanguageClient, text: str, version: int = 1) -> None:
    client.text_document_did_open(
        types.DidOpenTextDocumentParams(
            text_document=types.TextDocumentItem(
                uri=URI, language_id="tactus", version=version, text=text
            )
        )
    )


@pytest.mark.asyncio
async def test_unit_error_is_reported_at_its_range(client: LanguageClient):
    # `B * key` is N·s, `G` is N: E0202, the same code and message as `tactus check`.
    bad = HARPSICHORD.replace("force viscous = B * d(key)", "force viscous = B * key + G")
    open_doc(client, bad)
    await client.wait_for_notification(types.TEXT_DOCUMENT_PUBLISH_DIAGNOSTICS)
    diags = [d for d in client.diagnostics[URI] if d.code == "E0202"]
    assert len(diags) == 1, client.diagnostics[URI]
    d = diags[0]
    assert d.severity == types.DiagnosticSeverity.Error
    assert d.message.startswith("dimension mismatch: cannot add")
    start = position(bad, "B * key + G")
    assert d.range.start == start
    assert d.range.end == types.Position(
        line=start.line, character=start.character + len("B * key + G")
    )


@pytest.mark.asyncio
async def test_hover_definition_completion(client: LanguageClient):
    open_doc(client, HARPSICHORD)
    await client.wait_for_notification(types.TEXT_DOCUMENT_PUBLISH_DIAGNOSTICS)
    assert [d for d in client.diagnostics[URI] if d.severity == 1] == []
    doc = types.TextDocumentIdentifier(uri=URI)

    # Hover a term: the product `B * d(key)` is a force in newtons with a Q-format.
    hover = await client.text_document_hover_async(
        types.HoverParams(text_document=doc, position=position(HARPSICHORD, "* d(key)"))
    )
    text = hover.contents.value
    assert "term `B * d(key)`" in text, text
    assert "unit: N (force)" in text, text
    assert "format: Q" in text, text
    assert "error bound" in text and "DAC LSB" in text, text

    # Go to a component's definition from its `use`: the harpsichord imports it from Tactus's
    # library, whose file the server has written into its cache directory for the client.
    found = await client.text_document_definition_async(
        types.DefinitionParams(
            text_document=doc, position=position(HARPSICHORD, "plectrum(x = key", 3)
        )
    )
    loc = found[0] if isinstance(found, list) else found
    assert loc.uri.endswith("/action.tactus"), loc.uri
    lib_path = pathlib.Path(urllib.parse.unquote(urllib.parse.urlparse(loc.uri).path))
    assert lib_path.is_relative_to(CACHE.resolve()) or lib_path.is_relative_to(CACHE), lib_path
    lib_text = lib_path.read_text()
    assert "component plectrum {" in lib_text
    assert loc.range.start == position(lib_text, "plectrum {")

    # Hover the imported component: its file, its interface, its documentation.
    hover = await client.text_document_hover_async(
        types.HoverParams(text_document=doc, position=position(HARPSICHORD, "plectrum(x = key", 3))
    )
    text = hover.contents.value
    assert "component `plectrum`" in text, text
    assert "from: builtin:lib/action.tactus" in text, text
    assert "the quill bends against the string" in text, text

    # Complete a param: `force weight = |G` offers the instrument's params.
    items = await client.text_document_completion_async(
        types.CompletionParams(
            text_document=doc, position=position(HARPSICHORD, "force weight = G", len("force weight = "))
        )
    )
    items = items.items if hasattr(items, "items") else items
    by_label = {i.label: i for i in items}
    assert "G" in by_label and "B" in by_label, sorted(by_label)
    assert by_label["G"].kind == types.CompletionItemKind.Constant
    assert "param" in by_label["G"].detail
