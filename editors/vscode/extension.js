// Starts `idefix-verify lsp` for .rules files; highlighting comes from the TextMate grammar.
"use strict";

const vscode = require("vscode");
const { LanguageClient, TransportKind } = require("vscode-languageclient/node");

let client;

function activate() {
  const settings = vscode.workspace.getConfiguration("idefixRules");
  const serverOptions = {
    command: settings.get("server.command", "idefix-verify"),
    args: settings.get("server.args", ["lsp"]),
    transport: TransportKind.stdio,
  };
  const clientOptions = {
    documentSelector: [
      { scheme: "file", language: "idefix-rules" },
      { scheme: "untitled", language: "idefix-rules" },
    ],
  };
  client = new LanguageClient("idefix-rules", "IDEFIX rulebook", serverOptions, clientOptions);
  return client.start();
}

function deactivate() {
  return client ? client.stop() : undefined;
}

module.exports = { activate, deactivate };
