"""The rulebook language server (``idefix-verify lsp``) and what it knows about a rulebook.

The editor features are plain functions of the text, with no protocol in them: diagnostics
come from the checker itself (:func:`idefix_rules.rulebook.checking.check_source`, as
``check --strict``), :mod:`~idefix_rules.lsp.symbols` finds definitions and references,
:mod:`~idefix_rules.lsp.hover`, :mod:`~idefix_rules.lsp.completion` and
:mod:`~idefix_rules.lsp.fixes` answer the editor's questions, and formatting is ``fmt``'s own
:func:`~idefix_rules.rulebook.format.formatted_text`. Only :mod:`~idefix_rules.lsp.server`
speaks the protocol (through ``pygls``, the optional extra ``idefix-rules[lsp]``); positions in this
package are 0-based lines and columns counted in characters, converted to the client's units
there.
"""
