// The pilot's screen: wires the connection, the instruments, the charts, the panels and the
// input devices together. The server decides; this page shows and asks.

import { AlarmSound } from "./alarm.js";
import { Charts } from "./charts.js";
import { stampMs } from "./clock.js";
import { Connection } from "./connection.js";
import { InputDevices } from "./input.js";
import { isFlyingKey, typingIn } from "./keyboard.js";
import { drawAttitude, drawDepth, drawHeading, drawThrust } from "./instruments.js";
import { ACTIONS, AXES, loadMapping, pressed, resetMapping, saveMapping } from "./mapping.js";

const $ = (id) => document.getElementById(id);
const station = {
  id: null, pilotId: null, limits: null, telemetry: null, leakSilenced: false, telemetryCount: 0,
  leak: false,  // the leak latch as last read
  rateHz: 10, heartbeatMs: 1000,
  // When the station last said anything, and when the last reading of the robot came
  // (performance.now()); null: not since this socket opened.
  heardAt: null, readingAt: null,
  // Why this page is no longer the pilot, shown until it takes control again.
  lostControl: null,
  // The last STOP pressed (its stop_id) until the station says it stopped the robot: sent
  // again until it does, and first on a socket of the page's that opens.
  stopKept: null,
  // The pilot was told that STOP has not gone yet (and is told when it has).
  stopUnsent: false,
  // How long the fastest of this socket's timed messages took to arrive, the station's clock
  // against this page's (ms; null: none yet), and how much later than that the last one came.
  fastestArrivalMs: null, fastestAt: 0, lateMs: 0,
  // The station closed this page's socket on its way out (not a connection that dropped):
  // said until a socket opens again.
  closed: false,
  // Why the station refuses this page's sockets (a token it no longer takes), as it said;
  // null: not refused.
  refused: null,
};
// No word from the station (not even its heartbeat) for this long: the socket is given up and
// a new one opened. By then the station has dropped the old one too (serve.py pings every 5 s
// and gives up 5 s later), so the page does not come back as a second copy of itself.
const SILENT_RECONNECT_MS = 10000;
// The station's messages arrive this much later than the fastest did: a network slower than
// they are (each waits longer than the one before), and what is shown is that old.
const LATE_MS = 1000;

// The two clocks may drift apart this much (0.1 %: quartz does far better); a network that
// holds messages back makes them later much faster.
const CLOCK_DRIFT = 1e-3;

// A message stamped with the station's time ``t`` (s) arrived now: how late (see LATE_MS).
function measureLateness(t) {
  if (typeof t !== "number") return;
  const now = performance.now();
  const arrivalMs = now - t * 1000;
  let fastest = station.fastestArrivalMs;
  if (fastest !== null) fastest += Math.max(0, now - station.fastestAt) * CLOCK_DRIFT;
  if (fastest === null || arrivalMs < fastest) fastest = arrivalMs;
  station.fastestArrivalMs = fastest;
  station.fastestAt = now;
  station.lateMs = arrivalMs - fastest;
}
let mapping = loadMapping();
const alarm = new AlarmSound();
const charts = new Charts($("depth-chart"), $("attitude-chart"));
const connection = new Connection(onMessage, onConnectionState);

const isPilot = () => station.id !== null && station.pilotId === station.id && connection.isOpen;
const send = (message) => connection.send(message);
// What the pilot asks for while the page cannot reach the station (the connection dropped and
// is being reopened) is not sent, and the page says so: it would act later, unasked. STOP
// excepted: it is kept and sent first when the station is reached again (it can only make the
// robot safer; the station zeroed the thrust when the connection dropped, but only STOP locks
// the motors), and the pilot is told that it has not gone yet.
const ask = (message, what) => {
  if (send(message)) return true;
  toast(`not connected to the station: ${what} not sent`);
  return false;
};
// Stamped with this page's clock, as its input is: a command held up on a slow network is not
// sent when it arrives seconds later (the station says so).
const command = (name, values = []) => ask({ type: "command", name, values,
  sent_ms: stampMs() }, `#${[name, ...values].join(".")}!`);
// Each press of STOP goes over the page's WebSocket and over one of its own (/stop, opened for
// it): the page's socket may be stuck behind what it has still to send (a network slower than
// the pilot's input), or dead without either end knowing it yet (a Wi-Fi that roamed), and a
// STOP sent on it would wait there, or be lost with it. A new WebSocket is a new connection
// (an HTTP request may go on a kept-alive one, as dead). The station takes the first to arrive
// (by its stop_id). A STOP is kept until the station says it stopped the robot: with the
// network gone, the page's socket still takes what is sent on it, and loses it with itself.
const STOP_SESSION = Math.random().toString(36).slice(2, 10);
// How long after its own socket failed a STOP not taken yet is sent on another.
const STOP_RETRY_MS = 1000;
let stopsPressed = 0;
const stop = () => {
  stopsPressed += 1;
  const stopId = `${STOP_SESSION}-${stopsPressed}`;
  station.stopKept = stopId;
  stopOnItsOwn(stopId);
  if (send({ type: "stop", stop_id: stopId })) return;
  stopNotSent("STOP not sent yet: the station cannot be reached; it goes first when it is");
};
// The STOP kept (``stopId``) on a socket of its own, again every STOP_RETRY_MS until the
// station takes it (the station does it once, whichever way it came first).
function stopOnItsOwn(stopId) {
  connection.stopOnItsOwn({ stop_id: stopId, page_id: station.id }, () => {
    if (station.stopKept === stopId) stopTaken();
  }, () => {
    if (station.stopKept !== stopId) return;  // taken another way, or a newer STOP pressed
    stopNotSent("STOP not confirmed: the station cannot be reached; it is sent again until it is");
    setTimeout(() => { if (station.stopKept === stopId) stopOnItsOwn(stopId); }, STOP_RETRY_MS);
  });
}
function stopNotSent(why) {
  if (station.stopUnsent) return;
  station.stopUnsent = true;
  toast(why, null);
}
function stopTaken() {
  station.stopKept = null;
  if (station.stopUnsent) toast("STOP sent (pressed while the station could not be reached)");
  station.stopUnsent = false;
}

const devices = new InputDevices({
  send,
  act: (action) => {
    if (action === "stop") stop();
    else if (action === "unlock") command("start");
    else if (action === "claw_open") command("h+");
    else if (action === "claw_close") command("h-");
    else if (action === "mode") {
      const mode = station.telemetry?.commanded?.vertical_mode;
      command("mvdirect", [mode === "direct" ? 0 : 1]);
    }
  },
  isPilot,
  mapping: () => mapping,
  onChange: () => { renderDevices(); showFlightStatus(); },
});

// -- messages from the station -----------------------------------------------------------------

// The record button: the pilot starts and stops a recording on the server; every page sees it
// and can download the finished ones.
function showRecording(state) {
  const box = $("recording");
  box.hidden = state === null || state === undefined;
  if (box.hidden) return;
  station.recording = state;
  box.classList.toggle("active", state.active);
  $("record").textContent = state.active ? "■ Stop recording" : "● Record";
  $("record").disabled = !isPilot();
  let status = "";
  if (state.active) {
    status = `${state.file} · ${Math.round(state.elapsed_s ?? 0)} s · by ${state.started_by}`;
  }
  if (state.failure) status = state.failure;
  $("recording-status").textContent = status;
  const items = state.finished.map((item) => {
    const link = document.createElement("a");
    link.href = `/recordings/${encodeURIComponent(item.name)}`;
    link.download = item.name;
    const failed = item.failed ? ", stopped early" : "";
    link.textContent = `${item.name} (${(item.size_bytes / 1000).toFixed(1)} kB, ${item.duration_s} s${failed})`;
    const entry = document.createElement("li");
    entry.append(link);
    return entry;
  });
  $("recordings-list").replaceChildren(...items);
  $("recordings").hidden = items.length === 0;
}

function onMessage(message) {
  station.heardAt = performance.now();
  switch (message.type) {
    case "hello":
      // Another station, maybe (restarted): its clock is another.
      station.fastestArrivalMs = null;
      station.lateMs = 0;
      station.id = message.id;
      station.limits = message.limits;
      station.rateHz = message.rate_hz;
      station.heartbeatMs = message.heartbeat_ms ?? 1000;
      if (message.telemetry?.sensors) station.readingAt = station.heardAt;
      devices.resendMs = message.input_resend_ms;
      $("link-description").textContent = `· ${message.description} · you are ${message.label}`;
      $("log").replaceChildren();
      message.log.forEach(addLog);
      charts.clear();  // a reconnected page gets the whole history again
      message.history.forEach((row) => charts.add(row));
      buildSettings(message.limits);
      setControl(message.pilot_id, message.pilot_label);
      showTelemetry(message.telemetry);
      showRecording(message.recording);
      break;
    case "recording":
      showRecording(message);
      break;
    case "telemetry": {
      station.telemetryCount += 1;
      measureLateness(message.t);
      const s = message.sensors;
      if (s) station.readingAt = station.heardAt;
      showTelemetry(message);
      // A failed poll is a gap in the charts, not a line drawn across it.
      charts.add([message.t, s ? s.depth_cm : null, message.commanded.target_depth_cm,
        s ? s.roll_deg : null, s ? s.pitch_deg : null, s ? s.heading_deg : null]);
      break;
    }
    case "heartbeat":
      measureLateness(message.t);
      break;
    case "control":
      setControl(message.pilot_id, message.pilot_label, message.text);
      toast(message.text);
      break;
    case "log":
      addLog(message);
      break;
    case "error":
      toast(message.message);
      break;
  }
}

// A station that closes (Ctrl-C, SIGTERM) closes the pages' sockets as a server going away
// does: 1001 (going away) or 1012 (service restart). A connection that drops ends with 1006.
const STATION_CLOSED_CODES = [1001, 1012];

// A socket the station would not open: the browser does not say why (a refused WebSocket is
// a dropped one to the page), so the page asks the station for itself. A token that is no
// longer taken (the station restarted with a new one) is then said, not retried in silence.
async function askWhyRefused() {
  let refused = null;
  try {
    const response = await fetch("/", { cache: "no-store", credentials: "same-origin" });
    if (response.status === 403) refused = (await response.text()).trim().replace(/^rovlink web: /, "");
  } catch { /* not reachable: not refused */ }
  if (connection.isOpen) return;
  station.refused = refused;
  showFreshness();
}

// ``closeCode``: how a socket that was open closed (null: given up by this page, or never
// open); ``opened``: whether it ever opened.
function onConnectionState(state, closeCode = null, opened = true) {
  if (state === "open") { station.closed = false; station.refused = null; }
  else if (STATION_CLOSED_CODES.includes(closeCode)) station.closed = true;
  if (state === "closed" && !opened) askWhyRefused();
  const badge = $("connection");
  badge.className = "badge " + (state === "open" ? "ok" : "bad");
  badge.textContent = state === "open" ? "station connected"
    : station.closed ? "the station closed: reconnecting when it is back"
      : state === "connecting" ? "connecting…" : "station connection lost: reconnecting";
  // An open socket counts as word from the station: one that then says nothing is silent.
  station.heardAt = state === "open" ? performance.now() : null;
  station.readingAt = null;
  if (state === "open") {
    if (station.stopKept && send({ type: "stop", stop_id: station.stopKept })) stopTaken();
    // The station takes a new page as shown: one opened in a background tab says otherwise.
    if (document.hidden) send({ type: "visibility", hidden: true });
  } else {
    setControl(null, null, station.closed ? "the station closed"
      : "the connection to the station dropped");
  }
  showFreshness();
}

// -- what is shown is old ------------------------------------------------------------------------

// The station's heartbeat comes every second whatever the robot does; a reading every poll.
// Silence from either is shown: a network that stops without closing the socket leaves the
// last values on screen, and they must not pass for live ones.
let freshnessCheckedAt = performance.now();
function showFreshness() {
  const now = performance.now();
  // Silence counts only while this page runs: a tab the browser froze or throttled (hidden)
  // must not take the messages waiting for it as missing, and reconnect, when it wakes.
  const asleep = now - freshnessCheckedAt - 250;
  freshnessCheckedAt = now;
  if (asleep > 1000) {
    if (station.heardAt !== null) station.heardAt += asleep;
    if (station.readingAt !== null) station.readingAt += asleep;
  }
  let stale = "";
  let old = false;
  if (!connection.isOpen && station.refused) {
    stale = `the station refuses this page (${station.refused}): everything shown is old`;
    old = true;
  } else if (!connection.isOpen) {
    stale = `${station.closed ? "the station closed" : "not connected to the station"}: everything shown is old`;
    old = true;
  } else if (station.heardAt !== null && now - station.heardAt > 2.5 * station.heartbeatMs) {
    const silent = (now - station.heardAt) / 1000;
    stale = `no word from the station for ${silent.toFixed(0)} s (the network?): everything shown is old`;
    old = true;
    if (now - station.heardAt > SILENT_RECONNECT_MS) connection.reconnect();
  } else if (station.lateMs > LATE_MS) {
    const late = station.lateMs / 1000;
    stale = `what the station says arrives ${late.toFixed(1)} s late (a slow network?): everything shown is old`;
    old = true;
  } else if (station.readingAt === null
    || now - station.readingAt > Math.max(1000, 3000 / station.rateHz)) {
    const since = station.readingAt === null ? ""
      : ` for ${((now - station.readingAt) / 1000).toFixed(1)} s`;
    stale = `no reading from the robot${since}`;
  }
  document.body.classList.toggle("stale", old);
  document.body.classList.toggle("stale-readings", stale !== "");
  text("stale-banner", stale);
  $("stale-banner").hidden = stale === "";
  if (old) {
    const badge = $("connection");
    badge.className = "badge bad";
    if (connection.isOpen) badge.textContent = "station silent";
    else if (station.refused) text("connection", "refused by the station");
  }
}
setInterval(showFreshness, 250);

// -- showing the state ---------------------------------------------------------------------------

function setControl(pilotId, pilotLabel, why = null) {
  const wasMine = station.pilotId !== null && station.pilotId === station.id;
  station.pilotId = pilotId;
  const mine = pilotId !== null && pilotId === station.id;
  if (wasMine && !mine && !station.releasing) {
    station.lostControl = `you are no longer the pilot: ${why ?? "control changed"}`;
  }
  if (mine || station.releasing) station.lostControl = null;
  if (!mine) station.releasing = false;
  $("control").classList.toggle("pilot", mine);
  document.body.classList.toggle("watching", !mine);
  // Not connected, the page cannot know who has control (another page may have taken it):
  // it does not say "nobody".
  $("control-status").textContent = mine ? "you are the pilot"
    : !connection.isOpen ? "not connected: who has control is not known"
      : pilotId ? `watching: ${pilotLabel} has control` : "watching: nobody has control";
  station.pilotLabel = pilotLabel;
  $("release-control").hidden = !mine;
  showTakeQuestion();
  $("record").disabled = !mine;  // only the pilot starts and stops a recording
  // Disabled, not only greyed out: the keyboard and a screen reader get it too.
  for (const control of document.querySelectorAll(PILOT_CONTROLS)) control.disabled = !mine;
  showFlightStatus();
}

// What only the pilot may use (the settings rows are built when the station says hello). The
// leak alarm's *Silence* is this page's own sound: any page may use it.
const PILOT_CONTROLS = ".pilot-only button, .pilot-only input, #settings-rows button, #settings-rows input, #leak-reset";

// Taking control from another pilot asks first, on the page (see the take-control button).
function showTakeQuestion() {
  const mine = station.pilotId !== null && station.pilotId === station.id;
  if (mine || !station.pilotId) station.askingToTake = false;
  $("take-control-question").hidden = !station.askingToTake;
  $("take-control").hidden = mine || station.askingToTake;
  text("take-control-text", `Take control from ${station.pilotLabel}? Their thrust goes to zero.`);
}

// The banner under the top bar: the pilot is told why nothing moves; a page that lost control,
// why it did (until it takes control again).
// A pilot with no input device is told that first: the relay, which has heard no input, says
// "release the dead-man to arm", and there is no dead-man to release.
function showFlightStatus() {
  const status = station.telemetry?.relay?.status ?? "";
  const device = devices.active();
  const why = device.kind === null ? `${device.label} (nothing flies without an input device)`
    : status === "flying" || status.startsWith("armed") ? "" : status;
  text("flight-status", isPilot() ? why : station.lostControl ?? "");
}

// The relay row. The relay's status is the pilot's ("release the dead-man to arm", "unlock
// (#start!) to fly"): a watcher, and every page while nobody has control, is told instead what
// the robot does and who flies.
function relayText(t) {
  if (isPilot()) return t.relay.status;
  const c = t.commanded;
  // (A lock the controller announced goes before the lock as this station sent it.)
  const lock = c.heard_lock ?? c.lock;
  // With no motion relayed, a depth hold still drives the vertical thrusters.
  const holding = c.vertical_mode === "direct" ? null
    : c.target_depth_cm !== null ? `holding ${c.target_depth_cm} cm`
      : c.holding_entry_depth ? "holding its depth on entry" : null;
  const doing = lock === "locked" ? "motors locked"
    : t.relay.moving ? (lock === "unlocked" ? "flying" : "flying, if the motors are unlocked")
      : c.heard_lock ? `motors ${c.heard_lock} (${c.heard_lock_because})`
        : holding === null ? "no thrust"
          : lock === "unlocked" ? holding : `${holding}, if the motors are unlocked`;
  return `${doing}; ${t.pilot_label ? `${t.pilot_label} has control` : "nobody has control"}`;
}

function text(id, value) { const el = $(id); if (el.textContent !== value) el.textContent = value; }

function showTelemetry(t) {
  if (!t) return;
  station.telemetry = t;
  if (t.pilot_id !== station.pilotId) setControl(t.pilot_id, t.pilot_label);
  // Not armed: a dead-man already released is said again (the relay waits to hear it).
  if (isPilot() && t.relay && !t.relay.armed) devices.releaseAsked = true;
  const s = t.sensors, c = t.commanded;
  // Depth mode is the mode after a reset: a target sent without mvdirect is held.
  const target = c.vertical_mode !== "direct" ? c.target_depth_cm : null;
  drawAttitude($("attitude"), s?.roll_deg, s?.pitch_deg);
  drawHeading($("heading"), s?.heading_deg);
  drawDepth($("depth-gauge"), s?.depth_cm, target);
  drawThrust($("thrust"), c, devices.lastInput);
  text("roll-value", s ? `${s.roll_deg}°` : "–");
  text("pitch-value", s ? `${s.pitch_deg}°` : "–");
  text("heading-value", s ? `${s.heading_deg}°` : "–");
  text("depth-value", s ? `${s.depth_cm} cm` : "–");
  text("thrust-value", `${c.direction_deg}° at ${c.power_percent} %`);
  // A lock the controller announced (debug output on: another line's stop, a failsafe) is
  // shown with where it came from; else the lock as last sent.
  const lock = $("lock-state");
  lock.className = c.heard_lock ?? c.lock;
  text("lock-state", c.heard_lock ? `${c.heard_lock} (${c.heard_lock_because})`
    : c.lock !== "unknown" ? c.lock : c.lock_unknown_because
      ? `unknown: after ${c.lock_unknown_because}` : "not sent yet (locked after a reset)");
  const targetText = c.target_depth_cm !== null ? `target ${c.target_depth_cm} cm`
    : c.holding_entry_depth ? "holding its depth on entry" : "no target sent";
  const mode = c.vertical_mode === "direct"
    ? `direct, thrust ${c.vertical_thrust_percent >= 0 ? "+" : ""}${c.vertical_thrust_percent} %`
    : c.vertical_mode === "depth" ? `depth, ${targetText}`
      : `depth (the mode after a reset; mvdirect not sent), ${targetText}`;
  text("mode-state", mode);
  text("horizontal-state", `${c.direction_deg}° at ${c.power_percent} %`);
  const relayShown = relayText(t);
  const flying = relayShown === "flying" || relayShown.startsWith("flying;");
  $("relay-state").className = flying ? "flying" : "";
  text("relay-state", relayShown);
  showFlightStatus();
  showLink(t.link);
  showLeak(s);
}

// The last poll's round trip. A poll that failed (or a link that is down) had none: the last
// one answered is not passed off as the link's now.
function roundTripText(link) {
  if (link.round_trip_ms === null) return "–";
  const times = `${link.round_trip_ms.toFixed(1)} ms (avg ${link.average_round_trip_ms.toFixed(1)} ms)`;
  return link.connected && link.status === "ok" ? times : `none now; last answered: ${times}`;
}

const LINK_ROWS = [
  ["status", (l) => (l.connected ? l.status : "disconnected"), (l) => !l.connected || l.status !== "ok"],
  ["round trip", roundTripText, (l) => !l.connected || l.status !== "ok"],
  ["timeouts", (l) => String(l.timeouts), (l) => l.timeouts > 0],
  ["retries", (l) => String(l.retries)],
  ["checksum errors", (l) => String(l.checksum_errors), (l) => l.checksum_errors > 0],
  ["late replies", (l) => String(l.late_replies), (l) => l.late_replies > 0],
  ["suspected resets", (l) => String(l.resets_suspected), (l) => l.resets_suspected > 0],
  ["motion expiries", (l) => String(l.motion_expiries)],
  ["frames out / in", (l) => `${l.frames_sent} / ${l.frames_received}`],
  ["checksum mode", (l) => (l.checksum ? "on" : "off")],
];

function showLink(link) {
  const body = $("link-health").tBodies[0];
  if (body.rows.length !== LINK_ROWS.length) {
    body.replaceChildren(...LINK_ROWS.map(([name]) => {
      const row = document.createElement("tr");
      row.innerHTML = "<td></td><td></td>";
      row.cells[0].textContent = name;
      return row;
    }));
  }
  LINK_ROWS.forEach(([, value, bad], i) => {
    const cell = body.rows[i].cells[1];
    const shown = value(link);
    if (cell.textContent !== shown) cell.textContent = shown;
    cell.classList.toggle("bad", Boolean(bad && bad(link)));
  });
  const badge = $("connection");
  if (connection.isOpen) {
    badge.className = "badge " + (link.connected && link.status === "ok" ? "ok" : "warn");
    badge.textContent = link.connected ? `robot link ${link.status}` : "robot link lost";
  }
}

// The leak latch as last read: a failed poll (a timeout, the robot's link lost) says nothing of
// it, and the alarm stays until a reading says the latch is clear.
function showLeak(sensors) {
  if (sensors) station.leak = Boolean(sensors.leak);
  const leak = station.leak;
  if (!leak) station.leakSilenced = false;
  if (leak && !station.leakSilenced) alarm.start(); else alarm.stop();
  // The alarm the browser keeps silent (it plays none until the page is clicked or a key
  // pressed) is said to be silent, and how to hear it: short, the banner is on a phone too.
  const muted = alarm.playing && !alarm.audible;
  const fired = muted ? "latched until reset; no sound until the page is clicked"
    : "the leak sensor fired (latched until reset)";
  text("leak-detail", sensors ? fired : `${fired}, as last read: no reading from the robot now`);
  $("leak-alarm").hidden = !leak;
}

function addLog(entry) {
  const item = document.createElement("li");
  item.className = entry.level;
  const time = document.createElement("time");
  time.textContent = entry.at_s.toFixed(1).padStart(7);
  item.append(time, entry.text);
  const log = $("log");
  log.prepend(item);
  while (log.children.length > 300) log.lastChild.remove();
}

let toastTimer = null;
// A message at the bottom of the page for a few seconds (``shownMs``; null: until the next).
function toast(message, shownMs = 4000) {
  const el = $("toast");
  el.textContent = message;
  el.hidden = false;
  clearTimeout(toastTimer);
  if (shownMs !== null) toastTimer = setTimeout(() => { el.hidden = true; }, shownMs);
}

// -- settings from the command table ---------------------------------------------------------

const SETTINGS = [["mvpdp", "depth PID: P"], ["mvpdi", "depth PID: I"], ["mvpidd", "depth PID: D"],
  ["mgmp", "max PWM"], ["sdz", "depth zero (raw at the surface)"], ["sdk", "depth coefficient k"]];

function buildSettings(limits) {
  const rows = $("settings-rows");
  rows.replaceChildren();
  for (const [name, label] of SETTINGS) {
    const argument = limits[name].arguments[0];
    const row = document.createElement("form");
    row.className = "setting-row";
    row.innerHTML = `<label class="name"></label><input type="number" required step="1" autocomplete="off">
      <span class="muted"></span><button type="submit">Send</button>`;
    row.querySelector(".name").textContent = `${label} (#${name})`;
    row.querySelector(".name").htmlFor = `setting-${name}`;
    row.querySelector("button").setAttribute("aria-label", `Send ${label}`);
    const input = row.querySelector("input");
    Object.assign(input, { min: argument.min, max: argument.max, name, id: `setting-${name}` });
    row.querySelector(".muted").textContent = `${argument.min}–${argument.max} ${argument.unit}`;
    row.addEventListener("submit", (event) => {
      event.preventDefault();
      command(name, [Number(input.value)]);
    });
    rows.append(row);
  }
  const target = limits.mvd.arguments[0];
  Object.assign($("target-depth"), { min: target.min, max: target.max });
}

// -- input devices and mapping ---------------------------------------------------------------

let renderedDevices = null;
let learningStopOf = null;  // the slot of the pad whose STOP is being learnt (pad list)
function renderDevices() {
  const active = devices.active();
  const badge = $("device-status");
  badge.textContent = active.kind ? `input: ${active.label}` : active.label;
  badge.className = "badge " + (active.kind && !active.warning ? "ok" : "warn");
  const pads = devices.pads();
  const options = [["auto", "automatic (the one standard pad)"], ["keyboard", "keyboard"],
    ...pads.filter((pad) => !devices.ignored.has(pad.id)).map((pad) => [`pad:${pad.id}`, `gamepad: ${pad.id}`])];
  const choice = devices.choice;
  const chosen = !choice ? "auto" : choice.kind === "keyboard" ? "keyboard" : `pad:${choice.id}`;
  // What each pad does: the one in use flies; every other is read for its STOP only.
  const kind = devices.mappedKind(active);
  const roles = pads.map((pad) => {
    if (devices.ignored.has(pad.id)) return "";
    if (active.kind === "gamepad" && pad.index === active.pad.index) return " · in use";
    const button = devices.stopButtonOf(pad, kind);
    return button === null ? " · not read (its STOP button is not known: learn it)"
      : ` · its STOP (button ${button}) stops the robot; nothing else is read`;
  });
  // A pad read for its STOP only whose STOP can be learnt: not the kind the mapping is for.
  const learnable = pads.map((pad) => !devices.ignored.has(pad.id) && pad.id !== kind);
  if (choice && choice.kind === "gamepad" && !options.some(([value]) => value === chosen)) {
    options.push([chosen, `gamepad: ${choice.id} (not connected)`]);
  }
  // Rebuilt only when what it shows changed: a rebuild between a press and its release (the
  // badge changes as the focus leaves a field) would lose the click.
  const shown = JSON.stringify([options, chosen, pads.map((pad) => [pad.id, pad.mapping]),
    [...devices.ignored], roles, learnable, learningStopOf]);
  if (shown === renderedDevices) return;
  renderedDevices = shown;
  // Buttons, not a <select>: an open native dropdown keeps Space and Esc from the page, and
  // with them the pilot's STOP keys.
  const group = $("device-choice");
  const focused = group.contains(document.activeElement) ? document.activeElement.dataset.device : null;
  group.replaceChildren(...options.map(([value, label]) => {
    const button = document.createElement("button");
    button.type = "button";
    button.dataset.device = value;
    button.textContent = label;
    button.setAttribute("aria-pressed", String(value === chosen));
    return button;
  }));
  // The keyboard's place in the group is kept.
  if (focused) group.querySelector(`[data-device="${CSS.escape(focused)}"]`)?.focus();
  const list = $("pad-list");
  list.replaceChildren(...pads.map((pad, index) => {
    const row = document.createElement("div");
    const box = document.createElement("input");
    box.type = "checkbox";
    box.checked = devices.ignored.has(pad.id);
    box.addEventListener("change", () => devices.setIgnored(pad.id, box.checked));
    const label = document.createElement("label");
    label.append(box, ` ignore ${pad.id} (${pad.mapping || "non-standard"} mapping)${roles[index]}`);
    row.append(label);
    if (learnable[index]) {
      const learn = document.createElement("button");
      learn.type = "button";
      learn.dataset.learnStop = String(pad.index);
      learn.textContent = learningStopOf === pad.index ? "press its STOP…" : "learn its STOP";
      row.append(" ", learn);
    }
    return row;
  }));
}

// Learning another pad's STOP: the first of its buttons pressed that was not held when asked
// (within 5 s) is its STOP from then on, for every pad of its kind. Its press being learnt,
// still held, does nothing (the pad is seen for the first time again).
$("pad-list").addEventListener("click", (event) => {
  const slot = event.target.closest("button[data-learn-stop]")?.dataset.learnStop;
  if (slot === undefined || learningStopOf !== null) return;
  const pad = devices.pads().find((candidate) => candidate.index === Number(slot));
  if (!pad) return;
  const id = pad.id;
  const before = pad.buttons.map((_, index) => pressed(pad, index));
  const started = performance.now();
  learningStopOf = pad.index;
  renderDevices();
  const wait = setInterval(() => {
    const now = devices.pads().find((candidate) => candidate.index === pad.index && candidate.id === id);
    const index = now ? now.buttons.findIndex((_, i) => pressed(now, i) && !before[i]) : -1;
    if (index < 0 && now && performance.now() - started <= 5000) return;
    clearInterval(wait);
    learningStopOf = null;
    if (index >= 0) devices.setPadStop(id, index);
    else toast(now ? `no button of ${id} pressed: its STOP is as it was` : `${id} was unplugged`);
    renderDevices();
  }, 20);
});

$("device-choice").addEventListener("click", (event) => {
  const value = event.target.closest("button[data-device]")?.dataset.device;
  if (value === undefined) return;
  devices.choose(value === "auto" ? null : value === "keyboard" ? { kind: "keyboard" }
    : { kind: "gamepad", id: value.slice(4) });
});

function renderMapping() {
  const editor = $("mapping-editor");
  const table = document.createElement("table");
  const rows = [];
  for (const [name, label] of Object.entries(AXES)) {
    const axis = mapping.axes[name];
    rows.push(`<tr><td>${label}</td><td>axis <input type="number" min="0" max="15" autocomplete="off" data-axis="${name}" value="${axis.index}" aria-label="${label}: axis"></td>
      <td><label><input type="checkbox" data-invert="${name}" ${axis.invert ? "checked" : ""} aria-label="invert ${label}"> invert</label></td></tr>`);
  }
  for (const [name, label] of Object.entries(ACTIONS)) {
    rows.push(`<tr><td>${label}</td><td>button <input type="number" min="0" max="31" autocomplete="off" data-button="${name}" value="${mapping.buttons[name]}" aria-label="${label}: button"></td>
      <td><button type="button" data-learn="${name}" aria-label="learn ${label}">learn</button></td></tr>`);
  }
  table.innerHTML = rows.join("");
  const reset = document.createElement("button");
  reset.type = "button";
  reset.textContent = "default mapping";
  reset.addEventListener("click", () => { mapping = resetMapping(); renderMapping(); renderDevices(); });
  editor.replaceChildren(table, reset);
  table.addEventListener("change", (event) => {
    const el = event.target;
    if (el.dataset.invert) mapping.axes[el.dataset.invert].invert = el.checked;
    if (el.dataset.axis || el.dataset.button) {
      // A number the pad cannot have is refused and the old one kept: Number("") is 0 and a
      // button 40 never reads pressed, which would leave the pad's STOP doing nothing.
      const value = Number(el.value);
      const kept = el.dataset.axis ? mapping.axes[el.dataset.axis].index : mapping.buttons[el.dataset.button];
      if (el.value.trim() === "" || !Number.isInteger(value) || value < Number(el.min) || value > Number(el.max)) {
        const label = el.dataset.axis ? AXES[el.dataset.axis] : ACTIONS[el.dataset.button];
        const kind = el.dataset.axis ? "an axis" : "a button";
        toast(`${label}: ${kind} number ${el.min}–${el.max}, not "${el.value}"; kept ${kept}`);
        el.value = String(kept);
        return;
      }
      if (el.dataset.axis) mapping.axes[el.dataset.axis].index = value;
      else mapping.buttons[el.dataset.button] = value;
    }
    saveMapping(mapping);
    renderDevices();  // (the other pads' STOP button may have changed)
  });
  table.addEventListener("click", (event) => {
    const name = event.target.dataset?.learn;
    if (!name) return;
    const pad = devices.active().pad;
    if (!pad) { toast("choose a gamepad first"); return; }
    event.target.textContent = "press a button…";
    event.target.setAttribute("aria-label", `${ACTIONS[name]}: press a button…`);
    const before = pad.buttons.map((b) => b.pressed);
    const started = performance.now();
    devices.learning = true;
    const wait = setInterval(() => {
      const now = devices.active().pad;
      const index = now ? now.buttons.findIndex((b, i) => b.pressed && !before[i]) : -1;
      if (index >= 0 || performance.now() - started > 5000) {
        clearInterval(wait);
        // The button still held fires nothing: the pad's next reading is taken as a first one.
        devices.learning = false;
        devices.buttonsOf = null;
        if (index >= 0) { mapping.buttons[name] = index; saveMapping(mapping); }
        renderMapping();
        renderDevices();
      }
    }, 20);
  });
}

// -- buttons and keys -------------------------------------------------------------------------

$("stop").addEventListener("click", stop);
// Taking control from another pilot is asked on the page, not with confirm(): a browser
// dialog stops the page (no STOP key, no pad, no STOP button) until it is answered.
$("take-control").addEventListener("click", () => {
  // Taken from whom this page knows has it: the station refuses if another page took it
  // meanwhile, and the page then asks, as for any pilot.
  if (!station.pilotId) { ask({ type: "take_control", from: null }, "taking control"); return; }
  station.askingToTake = true;
  showTakeQuestion();
  $("take-control-no").focus();
});
$("take-control-yes").addEventListener("click", () => {
  station.askingToTake = false;
  showTakeQuestion();
  ask({ type: "take_control", from: station.pilotId }, "taking control");
});
$("take-control-no").addEventListener("click", () => { station.askingToTake = false; showTakeQuestion(); });
$("release-control").addEventListener("click", () => {
  station.releasing = true;  // (no "you are no longer the pilot" for letting go oneself)
  ask({ type: "release_control" }, "releasing control");
});
$("record").addEventListener("click", () => {
  const start = !station.recording?.active;
  ask({ type: start ? "record_start" : "record_stop" }, start ? "Record" : "Stop recording");
});
$("unlock").addEventListener("click", () => command("start"));
$("mode-depth").addEventListener("click", () => command("mvdirect", [0]));
$("mode-direct").addEventListener("click", () => command("mvdirect", [1]));
$("claw-open").addEventListener("click", () => command("h+"));
$("claw-close").addEventListener("click", () => command("h-"));
$("target-form").addEventListener("submit", (event) => {
  event.preventDefault();
  command("mvd", [Number($("target-depth").value)]);
});
$("leak-reset").addEventListener("click", () => command("slreset"));
$("leak-silence").addEventListener("click", () => { station.leakSilenced = true; alarm.stop(); });
$("keyboard-power").addEventListener("input", (event) => {
  devices.keyboard.powerPercent = Number(event.target.value);
  $("keyboard-power-value").textContent = `${event.target.value} %`;
});
$("keyboard-power").addEventListener("change", (event) => event.target.blur());

// Space and Esc stop the robot from anywhere on the page, before anything else sees the key.
// Nothing on the page may take these keys first: no native <select> (its open dropdown keeps
// them), no confirm() or alert() (the page stops until answered). Their default action is
// refused on the release too: Space on a focused button, box or summary is STOP, not a click.
const isStopKey = (event) => event.code === "Space" || event.code === "Escape";
addEventListener("keydown", (event) => {
  if (isStopKey(event)) {
    event.preventDefault();
    event.stopPropagation();
    if (!event.repeat) stop();
  }
}, { capture: true });
addEventListener("keyup", (event) => {
  if (isStopKey(event)) { event.preventDefault(); event.stopPropagation(); }
}, { capture: true });

// The pilot flying with the keys while another device is in use (a pad) flies nothing: told
// why, not left pressing keys that do nothing.
addEventListener("keydown", (event) => {
  if (event.repeat || !event.shiftKey || !isFlyingKey(event.code) || typingIn(event.target)) return;
  const device = devices.active();
  if (!isPilot() || device.kind === "keyboard") return;
  toast(`the keyboard flies nothing: the input device is ${device.kind ? device.label : "none"};`
    + " choose \"keyboard\" under Input device and mapping");
});

document.addEventListener("visibilitychange", () => send({ type: "visibility", hidden: document.hidden }));
addEventListener("pagehide", () => connection.close());
addEventListener("pageshow", (event) => { if (event.persisted) connection.resume(); });

renderMapping();
renderDevices();
connection.open();
window.rovlinkStation = { station, devices, connection, charts, alarm };
