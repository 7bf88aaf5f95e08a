// A viewer that speaks only the open Foxglove WebSocket protocol, through the
// official client (@foxglove/ws-protocol, with the `ws` package as its
// WebSocket), for slidetrack's live view tests.
//
//     node live_client_open.js URL OUT.json [IDLE_S] [TIMEOUT_S]
//
// Offers the subprotocol `foxglove.websocket.v1` only (the client's
// SUPPORTED_SUBPROTOCOL), retries the connection until TIMEOUT_S, subscribes
// to every channel as it is advertised and records each message it receives
// (topic, log time, payload in hex) until the server closes the
// connection or nothing arrives for IDLE_S seconds. Writes
// {"subprotocol", "channels", "messages", "errors"} to OUT.json; the test
// compares the messages with the session file. Exits 1 when it never connected.
"use strict";

const fs = require("fs");
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const WebSocket = require("ws");

const [url, out, idleArg, timeoutArg] = process.argv.slice(2);
const idleMs = 1000 * Number(idleArg ?? 5);
const deadline = Date.now() + 1000 * Number(timeoutArg ?? 30);

const channels = new Map();
const topicOfSubscription = new Map();
const messages = [];
const errors = [];
let subprotocol = null;
let idleTimer = null;

function finish(code) {
  fs.writeFileSync(out, JSON.stringify({ subprotocol, channels: [...channels.values()], messages, errors }));
  process.exit(code);
}

function touch(client) {
  clearTimeout(idleTimer);
  idleTimer = setTimeout(() => {
    client.close();
    finish(0);
  }, idleMs);
}

function connect() {
  const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
  const client = new FoxgloveClient({ ws });
  let opened = false;
  client.on("open", () => {
    opened = true;
    subprotocol = ws.protocol;
    touch(client);
  });
  client.on("advertise", (advertised) => {
    touch(client);
    for (const ch of advertised) {
      channels.set(ch.id, ch);
      topicOfSubscription.set(client.subscribe(ch.id), ch.topic);
    }
  });
  client.on("message", ({ subscriptionId, timestamp, data }) => {
    touch(client);
    const bytes = Buffer.from(data.buffer, data.byteOffset, data.byteLength);
    messages.push({
      topic: topicOfSubscription.get(subscriptionId),
      log_time: timestamp.toString(),
      data: bytes.toString("hex"),
    });
  });
  client.on("error", (e) => errors.push(String(e && e.message ? e.message : e)));
  client.on("close", () => {
    if (opened) {
      finish(0);
    } else if (Date.now() < deadline) {
      setTimeout(connect, 50);
    } else {
      finish(1);
    }
  });
}

connect();
