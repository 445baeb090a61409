// The language client of the Isaac extension: starts `isaac lsp` (the command and arguments of the settings
// isaac.server.command and isaac.server.args) over stdio for every .isaac file, and stops it with the editor.
"use strict";

const vscode = require("vscode");
const { LanguageClient, TransportKind } = require("vscode-languageclient/node");

let client;

function activate(context) {
  const settings = vscode.workspace.getConfiguration("isaac.server");
  const server = {
    command: settings.get("command", "isaac"),
    args: settings.get("args", ["lsp"]),
    transport: TransportKind.stdio,
  };
  const clientOptions = {
    documentSelector: [{ scheme: "file", language: "isaac" }],
  };
  client = new LanguageClient("isaac", "Isaac language server", server, clientOptions);
  context.subscriptions.push(client);
  return client.start();
}

function deactivate() {
  return client ? client.stop() : undefined;
}

module.exports = { activate, deactivate };
