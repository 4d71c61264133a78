"""The language server over stdio: the editor features of this package, spoken in LSP.

Built on ``pygls`` (the optional extra ``idefix-rules[lsp]``). Diagnostics are published when
a document opens and, debounced, after it changes (a burst of keystrokes is checked once, when
the typing pauses for :data:`DEBOUNCE_SECONDS`, or the ``debounce`` initialization option).
Every request works on an analysis of the document's current text: a request that arrives while
a check is still waiting for its debounce analyses the text at once.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Sequence
from typing import Any

from lsprotocol import types
from pygls.lsp.server import LanguageServer
from pygls.uris import to_fs_path
from pygls.workspace import TextDocument

from idefix_rules import __version__
from idefix_rules.errors import Diagnostic, IdefixError, Severity
from idefix_rules.lsp.analysis import Analysis, analyse
from idefix_rules.lsp.completion import Completion, completions
from idefix_rules.lsp.fixes import quick_fixes
from idefix_rules.lsp.hover import hover
from idefix_rules.lsp.positions import Position, Range, span_range
from idefix_rules.rulebook.format import formatted_text, with_line_endings

DEBOUNCE_SECONDS = 0.3
SOURCE = "idefix-rules"
_log = logging.getLogger(__name__)

_SEVERITIES = {Severity.ERROR: types.DiagnosticSeverity.Error,
               Severity.WARNING: types.DiagnosticSeverity.Warning}
_KINDS = {
    "constant": types.CompletionItemKind.Constant,
    "signal": types.CompletionItemKind.Variable,
    "variable": types.CompletionItemKind.Variable,
    "reducer": types.CompletionItemKind.Operator,
    "function": types.CompletionItemKind.Function,
    "unit": types.CompletionItemKind.Unit,
    "keyword": types.CompletionItemKind.Keyword,
    "index": types.CompletionItemKind.Field,
    "chance": types.CompletionItemKind.Event,
    "label": types.CompletionItemKind.EnumMember,
    "setting": types.CompletionItemKind.Property,
}


class RulebookServer(LanguageServer):
    """A language server for ``.rules`` files; one analysis per open document."""

    def __init__(self, debounce: float = DEBOUNCE_SECONDS) -> None:
        super().__init__("idefix-rules", __version__)
        self.debounce = debounce
        self.analyses: dict[str, tuple[int | None, Analysis]] = {}
        self.pending: dict[str, asyncio.Task[None]] = {}

    # ---- analyses

    def document(self, uri: str) -> TextDocument:
        """The open document, or the file of ``uri`` as it is on disk; a request for a
        document neither open nor readable is refused as invalid (-32602), never with an
        internal error's traceback."""
        document = self.workspace.get_text_document(uri)
        if not _is_open(self, uri):
            try:
                document.source  # noqa: B018 - read now: pygls reads an unopened one from disk
            except (OSError, UnicodeDecodeError, ValueError) as failure:
                from pygls.exceptions import JsonRpcInvalidParams

                raise JsonRpcInvalidParams(
                    message=f"{uri} is not open and cannot be read: "
                            f"{getattr(failure, 'strerror', None) or failure}") from None
        return document

    def analysis(self, uri: str) -> tuple[TextDocument, Analysis]:
        """The analysis of the document's current text (made now if the text is newer)."""
        document = self.document(uri)
        stored = self.analyses.get(uri)
        if stored is None or stored[0] != document.version or stored[1].text != _text(document):
            stored = (document.version, analyse(_text(document), document_path(uri)))
            self.analyses[uri] = stored
        return document, stored[1]

    def publish(self, uri: str) -> None:
        document, analysis = self.analysis(uri)
        self.text_document_publish_diagnostics(types.PublishDiagnosticsParams(
            uri=uri, version=document.version,
            diagnostics=[lsp_diagnostic(document, d) for d in analysis.diagnostics]))

    def schedule(self, uri: str) -> None:
        """Publish the diagnostics once the document has not changed for ``debounce`` s."""
        waiting = self.pending.pop(uri, None)
        if waiting is not None:
            waiting.cancel()
        self.pending[uri] = asyncio.get_running_loop().create_task(self._publish_later(uri))

    async def _publish_later(self, uri: str) -> None:
        await asyncio.sleep(self.debounce)
        self.pending.pop(uri, None)
        if uri in self.analyses or _is_open(self, uri):
            self.publish(uri)

    def forget(self, uri: str) -> None:
        waiting = self.pending.pop(uri, None)
        if waiting is not None:
            waiting.cancel()
        self.analyses.pop(uri, None)
        self.text_document_publish_diagnostics(types.PublishDiagnosticsParams(uri=uri,
                                                                              diagnostics=[]))


def _is_open(server: RulebookServer, uri: str) -> bool:
    return uri in server.workspace.text_documents


def _text(document: TextDocument) -> str:
    # as a file is read for `check`: universal newlines
    return document.source.replace("\r\n", "\n").replace("\r", "\n")


def document_path(uri: str) -> str:
    """The path diagnostics name: the file's path, or the URI of an unsaved buffer."""
    return to_fs_path(uri) or uri


# ----------------------------------------------------------------------------- conversions

def client_range(document: TextDocument, where: Range) -> types.Range:
    lines = document.lines
    start = _client_position(document, lines, where.start)
    end = _client_position(document, lines, where.end)
    return types.Range(start=start, end=end)


def _client_position(document: TextDocument, lines: Sequence[str],
                     position: Position) -> types.Position:
    if position.line >= len(lines):
        last = len(lines) - 1 if lines else 0
        text = lines[last].rstrip("\r\n") if lines else ""
        return types.Position(line=last, character=document.position_codec.client_num_units(text))
    return document.position_codec.position_to_client_units(
        lines, types.Position(line=position.line, character=position.character))


def server_position(document: TextDocument, position: types.Position) -> Position:
    found = document.position_codec.position_from_client_units(document.lines, position)
    return Position(found.line, found.character)


def lsp_diagnostic(document: TextDocument, diagnostic: Diagnostic) -> types.Diagnostic:
    """A checker diagnostic as the editor shows it: range, severity, code, message and hint."""
    message = diagnostic.message + (f"\nhint: {diagnostic.hint}" if diagnostic.hint else "")
    return types.Diagnostic(
        range=client_range(document, span_range(diagnostic.span)),
        message=message,
        severity=_SEVERITIES[diagnostic.severity],
        code=diagnostic.code,
        source=SOURCE,
        data={"hint": diagnostic.hint} if diagnostic.hint else None,
    )


def _location(uri: str, document: TextDocument, where: Range) -> types.Location:
    return types.Location(uri=uri, range=client_range(document, where))


def _completion_item(document: TextDocument, item: Completion) -> types.CompletionItem:
    return types.CompletionItem(
        label=item.label, kind=_KINDS[item.kind], detail=item.detail,
        text_edit=types.TextEdit(range=client_range(document, item.range), new_text=item.label))


def whole_document(document: TextDocument) -> types.Range:
    """From the start to the very end of the text (after its last newline, if any)."""
    segments = document.source.split("\n")
    end = types.Position(line=len(segments) - 1,
                         character=document.position_codec.client_num_units(segments[-1]))
    return types.Range(start=types.Position(line=0, character=0), end=end)


# ----------------------------------------------------------------------------- features

def create_server(debounce: float = DEBOUNCE_SECONDS) -> RulebookServer:
    """A server with every feature registered (start it with ``start_io()``)."""
    server = RulebookServer(debounce)

    @server.feature(types.INITIALIZE)
    def initialize(ls: RulebookServer, params: types.InitializeParams) -> None:
        options: Any = params.initialization_options
        if isinstance(options, dict) and isinstance(options.get("debounce"), int | float):
            ls.debounce = max(0.0, float(options["debounce"]))

    @server.feature(types.TEXT_DOCUMENT_DID_OPEN)
    def did_open(ls: RulebookServer, params: types.DidOpenTextDocumentParams) -> None:
        ls.publish(params.text_document.uri)

    @server.feature(types.TEXT_DOCUMENT_DID_CHANGE)
    def did_change(ls: RulebookServer, params: types.DidChangeTextDocumentParams) -> None:
        ls.schedule(params.text_document.uri)

    @server.feature(types.TEXT_DOCUMENT_DID_SAVE)
    def did_save(ls: RulebookServer, params: types.DidSaveTextDocumentParams) -> None:
        ls.schedule(params.text_document.uri)

    @server.feature(types.TEXT_DOCUMENT_DID_CLOSE)
    def did_close(ls: RulebookServer, params: types.DidCloseTextDocumentParams) -> None:
        ls.forget(params.text_document.uri)

    @server.feature(types.TEXT_DOCUMENT_HOVER)
    def on_hover(ls: RulebookServer, params: types.HoverParams) -> types.Hover | None:
        document, analysis = ls.analysis(params.text_document.uri)
        found = hover(analysis, server_position(document, params.position))
        if found is None:
            return None
        return types.Hover(
            contents=types.MarkupContent(kind=types.MarkupKind.Markdown, value=found.markdown),
            range=client_range(document, found.range))

    @server.feature(types.TEXT_DOCUMENT_DEFINITION)
    def definition(ls: RulebookServer,
                   params: types.DefinitionParams) -> types.Location | None:
        uri = params.text_document.uri
        document, analysis = ls.analysis(uri)
        found = analysis.symbols.symbol_at(server_position(document, params.position))
        return _location(uri, document, found[0].definition) if found else None

    @server.feature(types.TEXT_DOCUMENT_REFERENCES)
    def references(ls: RulebookServer,
                   params: types.ReferenceParams) -> list[types.Location] | None:
        uri = params.text_document.uri
        document, analysis = ls.analysis(uri)
        found = analysis.symbols.symbol_at(server_position(document, params.position))
        if found is None:
            return None
        symbol = found[0]
        places = ([symbol.definition] if params.context.include_declaration else []) \
            + symbol.references
        return [_location(uri, document, where) for where in places]

    @server.feature(types.TEXT_DOCUMENT_COMPLETION,
                    types.CompletionOptions(trigger_characters=[".", "[", "("]))
    def complete(ls: RulebookServer, params: types.CompletionParams) -> types.CompletionList:
        document = ls.document(params.text_document.uri)
        items = completions(_text(document), server_position(document, params.position))
        return types.CompletionList(is_incomplete=False,
                                    items=[_completion_item(document, i) for i in items])

    @server.feature(types.TEXT_DOCUMENT_FORMATTING)
    def formatting(ls: RulebookServer,
                   params: types.DocumentFormattingParams) -> list[types.TextEdit] | None:
        uri = params.text_document.uri
        document = ls.document(uri)
        source = _text(document)
        try:
            text = formatted_text(source, document_path(uri))
        except IdefixError as failure:  # a syntax error: the diagnostics already say where
            ls.window_show_message(types.ShowMessageParams(
                type=types.MessageType.Warning,
                message=f"not formatted: {failure}"))
            return None
        text = with_line_endings(text, document.source)  # as fmt writes the file
        if text == document.source:
            return []
        return [types.TextEdit(range=whole_document(document), new_text=text)]

    @server.feature(types.TEXT_DOCUMENT_CODE_ACTION,
                    types.CodeActionOptions(code_action_kinds=[types.CodeActionKind.QuickFix]))
    def code_action(ls: RulebookServer,
                    params: types.CodeActionParams) -> list[types.CodeAction] | None:
        uri = params.text_document.uri
        document, analysis = ls.analysis(uri)
        start = server_position(document, params.range.start)
        end = server_position(document, params.range.end)
        wanted = Range(start, end)
        actions = []
        for fix in quick_fixes(analysis):
            if not span_range(fix.diagnostic.span).overlaps(wanted):
                continue
            edit = types.TextEdit(range=client_range(document, fix.range), new_text=fix.new_text)
            actions.append(types.CodeAction(
                title=fix.title, kind=types.CodeActionKind.QuickFix,
                diagnostics=[lsp_diagnostic(document, fix.diagnostic)], is_preferred=True,
                edit=types.WorkspaceEdit(changes={uri: [edit]})))
        return actions

    return server


def serve(debounce: float = DEBOUNCE_SECONDS) -> None:
    """Run the server on stdin/stdout until the client says exit."""
    create_server(debounce).start_io()
