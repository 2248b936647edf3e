// The WebSocket to the station: JSON messages both ways, reconnecting after a drop.
// The server's watchdog, not this code, keeps the robot safe when the socket dies.

// How long a STOP's own socket is kept open for its answer.
const STOP_SOCKET_MS = 10000;

function socketUrl(path) {
  const scheme = location.protocol === "https:" ? "wss:" : "ws:";
  return `${scheme}//${location.host}${path}`;
}

export class Connection {
  constructor(onMessage, onState) {
    this.onMessage = onMessage;
    this.onState = onState;
    this.socket = null;
    this.retryMs = 500;
    this.closedForGood = false;
  }

  open() {
    const socket = new WebSocket(socketUrl("/ws"));
    this.socket = socket;
    this.onState("connecting");
    let opened = false;
    socket.addEventListener("open", () => { opened = true; this.retryMs = 500; this.onState("open"); });
    socket.addEventListener("message", (event) => {
      let message;
      try { message = JSON.parse(event.data); } catch { return; }
      this.onMessage(message);
    });
    socket.addEventListener("close", (event) => {
      if (this.socket !== socket) return;
      this.socket = null;
      this.onState("closed", event.code, opened);
      if (this.closedForGood) return;
      setTimeout(() => this.open(), this.retryMs);
      this.retryMs = Math.min(this.retryMs * 2, 5000);
    });
  }

  get isOpen() { return this.socket !== null && this.socket.readyState === WebSocket.OPEN; }

  // The station went silent on an open socket (a network that stopped without closing it):
  // give that socket up, without waiting for its closing handshake, and open a new one.
  reconnect() {
    const socket = this.socket;
    if (this.closedForGood) return;
    this.socket = null;
    if (socket) {
      try { socket.close(); } catch { /* already closing */ }
    }
    this.onState("closed");
    this.open();
  }

  // A page brought back from the back/forward cache: its socket was closed when it was left.
  resume() {
    if (!this.closedForGood) return;
    this.closedForGood = false;
    this.retryMs = 500;
    if (!this.socket) this.open();
  }

  // A STOP on a WebSocket of its own (a new connection: see main.js); stopped() once the
  // station says it stopped the robot, unanswered() if the socket closed (or was given up)
  // without that: the station could not be reached.
  stopOnItsOwn(message, stopped, unanswered) {
    let answered = false;
    const giveUp = () => { if (!answered) { answered = true; unanswered(); } };
    let socket;
    try { socket = new WebSocket(socketUrl("/stop")); } catch { giveUp(); return; }
    socket.addEventListener("open", () => socket.send(JSON.stringify(message)));
    socket.addEventListener("message", (event) => {
      if (!answered && event.data === "stopped") { answered = true; stopped(); }
      socket.close();
    });
    socket.addEventListener("close", giveUp);
    setTimeout(() => { socket.close(); giveUp(); }, STOP_SOCKET_MS);
  }

  send(message) {
    if (!this.isOpen) return false;
    this.socket.send(JSON.stringify(message));
    return true;
  }

  close() {
    this.closedForGood = true;
    if (this.socket) this.socket.close();
  }
}
