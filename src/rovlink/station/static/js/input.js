// The pilot's input devices: gamepads (the browser Gamepad API) and the keyboard.
//
// Nothing is picked silently: the pad in use is the one the pilot chose, or — when no choice
// is saved — the one pad with the standard mapping when exactly one is connected. Pads on the
// ignore list (a headset, a keyboard that reports as a pad) are never used. Every few
// milliseconds the chosen device is read; the input goes to the server when it changes and,
// while the dead-man is held, at a steady rate, so the server's watchdog sees a frozen page
// or pad at once.
//
// Pad buttons fire on a press, not while held. STOP fires from any page that is shown, pilot
// or not, as the STOP button on the screen does; the other buttons only for the pilot.
//
// Every other pad in reach (a co-pilot's, a spare) is read for its STOP button and nothing
// else: it stops the robot and can move nothing. Its STOP is the mapping's for a pad of the
// kind the mapping is for (the same id as the chosen pad), else the one learnt for its kind
// (its id) in the pad list, else the standard layout's for a pad with the standard mapping; a
// pad of another kind without it and with no STOP learnt, or on the ignore list, is not read
// at all. Its STOP is never guessed (any button of it, say): a headset's volume key, or a
// button that reads "pressed" now and then on a worn pad, would stop the robot in mid-flight.

import { stampMs } from "./clock.js";
import { Keyboard, typingIn } from "./keyboard.js";
import { DEFAULT_MAPPING, padInput, pressed } from "./mapping.js";

const CHOICE_KEY = "rovlink.device";
const IGNORE_KEY = "rovlink.ignored-pads";
const PAD_STOPS_KEY = "rovlink.pad-stops";
const MAX_BUTTON = 31;
const POLL_MS = 10;
const BUTTON_ACTIONS = ["unlock", "stop", "claw_open", "claw_close", "mode"];

function loadJson(key, fallback) {
  try { return JSON.parse(localStorage.getItem(key)) ?? fallback; } catch { return fallback; }
}

// The STOP button learnt for each kind of pad (by id), as saved: a saved value that is not a
// button number is left out (that pad is then not read, as before it was learnt).
function loadPadStops() {
  const saved = loadJson(PAD_STOPS_KEY, {});
  const stops = new Map();
  if (typeof saved !== "object" || Array.isArray(saved)) return stops;
  for (const [id, button] of Object.entries(saved)) {
    if (Number.isInteger(button) && button >= 0 && button <= MAX_BUTTON) stops.set(id, button);
  }
  return stops;
}

// A pad as connected: its slot and its id (another pad in the same slot is another pad).
function padKey(pad) { return `${pad.index}:${pad.id}`; }

export class InputDevices {
  // send(message) sends to the server; act(name) runs a button's action; isPilot() says
  // whether this page flies; mapping() the current pad mapping.
  constructor({ send, act, isPilot, mapping, onChange }) {
    this.send = send;
    this.act = act;
    this.isPilot = isPilot;
    this.mapping = mapping;
    this.onChange = onChange;
    this.keyboard = new Keyboard(() => this.isPilot() && this.active().kind === "keyboard");
    this.choice = loadJson(CHOICE_KEY, null);      // {kind: "gamepad", id} | {kind: "keyboard"}
    this.ignored = new Set(loadJson(IGNORE_KEY, []));
    this.padStops = loadPadStops();  // id -> its STOP button, learnt in the pad list
    this.lastSent = null;
    this.lastSentAt = 0;
    this.resendMs = 50;
    this.previousButtons = {};
    this.buttonsOf = null;  // the pad previousButtons were read from
    // Every other pad's STOP as last read, by padKey(): a pad not in it is seen for the first
    // time, and its STOP held then is no press.
    this.otherStops = new Map();
    this.learning = false;  // a button of the mapping is being learnt
    this.deadmanHeldOff = false;  // since learning: until the dead-man reads released
    this.status = "";
    this.lastInput = null;
    // The station cut the relay (STOP, a new pilot, a reopened link...): it arms again once it
    // hears the dead-man released. Sent once if it is, else nothing but a press would be sent
    // (the page sends on changes), and the pilot would have to press, release and press again.
    this.releaseAsked = false;
    addEventListener("gamepadconnected", () => this.onChange());
    addEventListener("gamepaddisconnected", () => this.onChange());
    setInterval(() => this.poll(), POLL_MS);
  }

  pads() {
    let pads = [];
    try {
      pads = navigator.getGamepads ? Array.from(navigator.getGamepads()) : [];
    } catch { /* refused outside a secure context: no pads */ }
    return pads.filter((pad) => pad && pad.connected);
  }

  usablePads() { return this.pads().filter((pad) => !this.ignored.has(pad.id)); }

  choose(choice) {
    this.choice = choice;
    if (choice) localStorage.setItem(CHOICE_KEY, JSON.stringify(choice));
    else localStorage.removeItem(CHOICE_KEY);
    this.onChange();
  }

  // A pad of kind ``id`` (not the one in use) stops the robot with ``button`` from now on. A
  // button held as it is learnt is no press: each such pad is seen for the first time again.
  setPadStop(id, button) {
    this.padStops.set(id, button);
    localStorage.setItem(PAD_STOPS_KEY, JSON.stringify(Object.fromEntries(this.padStops)));
    for (const key of [...this.otherStops.keys()]) {
      if (key.slice(key.indexOf(":") + 1) === id) this.otherStops.delete(key);
    }
    this.onChange();
  }

  setIgnored(id, ignored) {
    if (ignored) this.ignored.add(id); else this.ignored.delete(id);
    localStorage.setItem(IGNORE_KEY, JSON.stringify([...this.ignored]));
    this.onChange();
  }

  // The device in use: {kind, pad?, label} or {kind: null, label: why none}.
  active() {
    const pads = this.usablePads();
    const choice = this.choice;
    if (choice && choice.kind === "keyboard") {
      let label = "keyboard";
      if (typingIn(document.activeElement)) {
        label = "keyboard (paused while typing in a field: click the page to fly)";
      } else if (this.keyboard.lapsed) {
        // The system stopped repeating it: its key-up may have been lost, or another key held
        // with it was let go of (only the key pressed last repeats).
        label = "keyboard (a key held with no repeat from the system was taken as released: press it again)";
      }
      return { kind: "keyboard", label, warning: label !== "keyboard" };
    }
    if (choice && choice.kind === "gamepad") {
      const pad = pads.find((candidate) => candidate.id === choice.id);
      if (pad) return { kind: "gamepad", pad, label: pad.id };
      return { kind: null, label: "the chosen gamepad is not connected" };
    }
    const standard = pads.filter((pad) => pad.mapping === "standard");
    if (standard.length === 1) return { kind: "gamepad", pad: standard[0], label: standard[0].id };
    if (pads.length === 0 && !window.isSecureContext) {
      // Some browsers show gamepads only to secure pages: https, or http on this computer.
      return { kind: null, label: "no gamepad (this browser may hide them from http pages of other computers: use an SSH tunnel)" };
    }
    if (pads.length === 0) return { kind: null, label: "no gamepad: connect one or choose the keyboard" };
    if (standard.length === 0) {
      return { kind: null, label: "no gamepad with the standard mapping: choose a device" };
    }
    return { kind: null, label: "several gamepads: choose one" };
  }

  // The kind of pad the mapping is for: the pad in use, or the one chosen (unplugged).
  mappedKind(device = this.active()) {
    if (device.kind === "gamepad") return device.pad.id;
    return this.choice && this.choice.kind === "gamepad" ? this.choice.id : null;
  }

  // The STOP button of a pad that is not the one in use; null: the pad is not read.
  stopButtonOf(pad, mappedKind, mapping = this.mapping()) {
    if (pad.id === mappedKind) return mapping.buttons.stop;
    if (this.padStops.has(pad.id)) return this.padStops.get(pad.id);
    if (pad.mapping === "standard") return DEFAULT_MAPPING.buttons.stop;
    return null;
  }

  // The other pads in reach: their STOP, on the press, from a page that is shown (pilot or
  // not, learning or not: what is learnt is the pad in use's press). Nothing else is read.
  pollOtherStops(device, mapping, shown) {
    const inUse = device.kind === "gamepad" ? device.pad : null;
    const kind = this.mappedKind(device);
    const seen = new Map();
    for (const pad of this.usablePads()) {
      if (inUse !== null && pad.index === inUse.index) continue;
      const button = this.stopButtonOf(pad, kind, mapping);
      if (button === null) continue;
      const key = padKey(pad);
      const down = pressed(pad, button);
      if (shown && down && this.otherStops.get(key) === false) this.act("stop");
      seen.set(key, down);
    }
    this.otherStops = seen;  // a pad gone and back is seen for the first time again
  }

  poll() {
    const device = this.active();
    if (device.label !== this.status) { this.status = device.label; this.onChange(); }
    const shown = !document.hidden;
    const flying = shown && this.isPilot();
    // Button presses are edges: a button already held when this page became the pilot (or
    // came back into view, or the pad was first seen: the press that shows a pad to the page)
    // does nothing until it is released and pressed again.
    const mapping = this.mapping();
    const pad = device.kind === "gamepad" ? device.pad : null;
    const samePad = pad !== null && this.buttonsOf !== null
      && this.buttonsOf.id === pad.id && this.buttonsOf.index === pad.index;
    for (const action of BUTTON_ACTIONS) {
      const down = pad !== null && pressed(pad, mapping.buttons[action]);
      // While a button is being learnt its press is the answer, not an action: only the
      // pilot's STOP still acts (a watcher learning its pad must not stop another's flight).
      const allowed = action === "stop" ? shown && (flying || !this.learning)
        : flying && !this.learning;
      if (allowed && samePad && down && !this.previousButtons[action]) this.act(action);
      this.previousButtons[action] = down;
    }
    this.buttonsOf = pad === null ? null : { id: pad.id, index: pad.index };
    this.pollOtherStops(device, mapping, shown);
    if (!flying) {
      this.lastSent = null;
      this.lastInput = null;  // the stick is drawn only while it flies
      return;
    }
    let input = null;
    if (device.kind === "gamepad") {
      input = { ...padInput(device.pad, mapping), pad_timestamp_ms: device.pad.timestamp,
        source: "gamepad" };
      // The press being learnt is the answer, not the dead-man: it moves nothing, and nor does
      // it held on after (the button learnt may be the dead-man's) until it is let go.
      if (this.learning) this.deadmanHeldOff = true;
      if (this.deadmanHeldOff) {
        if (!this.learning && !input.deadman) this.deadmanHeldOff = false;
        input.deadman = false;
      }
    } else if (device.kind === "keyboard") {
      input = { ...this.keyboard.input(), source: "keyboard" };
    } else if (this.lastSent && this.lastSent.deadman) {
      input = { ...this.lastSent, deadman: false, power_percent: 0, vertical_percent: 0 };
    }
    this.lastInput = input;
    if (input === null) return;
    const now = performance.now();
    const released = this.releaseAsked && !input.deadman;
    this.releaseAsked = false;
    const changed = released || !this.lastSent || ["deadman", "direction_deg", "power_percent",
      "vertical_percent", "source"].some((key) => input[key] !== this.lastSent[key]);
    if (changed || (input.deadman && now - this.lastSentAt >= this.resendMs)) {
      // Stamped with this page's clock: the station measures how late each one arrives.
      if (this.send({ type: "input", ...input, sent_ms: stampMs() })) {
        this.lastSent = input;
        this.lastSentAt = now;
      }
    }
  }
}
