// The keyboard as a flying device: Shift is the dead-man, W A S D or the arrows the direction,
// R and F up and down.
//
// A page is told when a key goes down and when it comes up; it cannot ask whether a key is
// held. A key-up the page never gets would leave the key held for good, and the robot flying on
// it: the window left (its key-ups go to the other window), a field focused, the browser's own
// menu opened (the key-ups go to the menu), the tab hidden, or a key-up the system keeps for
// itself (macOS sends none for a key let go while Cmd is down; a global shortcut). The first
// four let go of every key at once. For the rest, what is held must keep being confirmed:
//
// - The system repeats the key pressed last while it is held (a keydown with `repeat`, every
//   30-100 ms after 250-1000 ms), and only that key: each repeat confirms every flying key held
//   (the others held with it are not repeated). A flying key with no repeat for
//   `repeatConfirmMs` after the last one, or `pressConfirmMs` after its own press, is taken as
//   released: thrust to zero, and it must be pressed again. A press confirms only itself: a
//   stale key is not kept alive by the pilot pressing another.
// - Shift, the dead-man, is confirmed by every key event's own word on it (`shiftKey`, the
//   browser's): one that says Shift is up lets it go at once, one that says it is down confirms
//   it. Unconfirmed for as long, it reads released until a key event says it is down again.

// A key pressed in a field the pilot types in (the depth target, a setting) is not a flying
// key: Shift with the arrows selects text there.
export function typingIn(target) {
  if (!(target instanceof Element)) return false;
  if (target.isContentEditable || target.tagName === "TEXTAREA") return true;
  return target.tagName === "INPUT"
    && !["button", "submit", "reset", "checkbox", "radio"].includes(target.type);
}

// How long a key held is trusted after its press (the system's delay before repeating: 250 ms to
// 1 s, 500-660 ms by default) and after the last repeat (the next is due within 30-400 ms).
export const PRESS_CONFIRM_MS = 1200;
export const REPEAT_CONFIRM_MS = 500;

const DEADMAN_KEYS = ["ShiftLeft", "ShiftRight"];
// The keys that move the robot. Other keys are not kept, and their repeats confirm nothing (a
// key held for something else says nothing of these).
const FLYING_KEYS = ["KeyW", "KeyA", "KeyS", "KeyD", "ArrowUp", "ArrowDown", "ArrowLeft",
  "ArrowRight", "KeyR", "KeyF"];
export const isFlyingKey = (code) => FLYING_KEYS.includes(code);
// Keys that fly and that the browser would also act on: the arrows scroll the page.
const SCROLLING_KEYS = ["ArrowUp", "ArrowDown", "ArrowLeft", "ArrowRight"];

export class Keyboard {
  // flying() says whether the keys fly the robot now (the keyboard in use, on the pilot's page).
  constructor(flying = () => false) {
    this.pressConfirmMs = PRESS_CONFIRM_MS;
    this.repeatConfirmMs = REPEAT_CONFIRM_MS;
    this.held = new Map();  // key code -> until when it is trusted held (performance.now())
    this.powerPercent = 40;
    // The flying keys taken as released for want of a repeat: the page says so until they
    // are let go of (their key-up comes), every key is let go of, or a key is pressed.
    this.lapsedKeys = new Set();
    addEventListener("keydown", (event) => {
      if (typingIn(event.target)) return;
      this.keyDown(event);
      // The arrows fly the robot, and nothing else: the instruments must not scroll away.
      if (SCROLLING_KEYS.includes(event.code) && flying()) event.preventDefault();
    });
    addEventListener("keyup", (event) => {
      this.held.delete(event.code);
      this.lapsedKeys.delete(event.code);
      this.shiftSays(event, performance.now() + this.pressConfirmMs);
      // Nothing held any more: there is nothing to press again (a lapsed key's own key-up may
      // be the one that never came).
      if (this.held.size === 0) this.lapsedKeys.clear();
    });
    addEventListener("blur", () => this.releaseAll());
    // The browser's menu takes the key-ups of the keys let go while it is open.
    addEventListener("contextmenu", () => this.releaseAll());
    document.addEventListener("visibilitychange", () => { if (document.hidden) this.releaseAll(); });
    // Moving into a field lets go of every key held: the dead-man too.
    addEventListener("focusin", (event) => { if (typingIn(event.target)) this.releaseAll(); });
  }

  releaseAll() { this.held.clear(); }

  // A flying key was taken as released for want of a repeat, and is not let go of yet.
  get lapsed() { return this.lapsedKeys.size > 0; }

  keyDown(event) {
    const now = performance.now();
    const kept = FLYING_KEYS.includes(event.code) || DEADMAN_KEYS.includes(event.code);
    if (kept && event.repeat) {
      // The system repeats the key pressed last, and only while it is held: every flying key
      // held with it is confirmed (a key repeated that was let go of here is held again).
      const until = now + this.repeatConfirmMs;
      for (const code of [...this.held.keys(), event.code]) {
        if (FLYING_KEYS.includes(code)) this.held.set(code, until);
      }
    } else if (kept) {
      this.held.set(event.code, now + this.pressConfirmMs);
      this.lapsedKeys.clear();
    }
    this.shiftSays(event, now + (event.repeat ? this.repeatConfirmMs : this.pressConfirmMs));
  }

  // What a key event says of Shift: up (its key-up was lost: let go), or down (confirmed).
  shiftSays(event, until) {
    for (const code of DEADMAN_KEYS) {
      if (!event.shiftKey) this.held.delete(code);
      else if (this.held.has(code)) this.held.set(code, Math.max(this.held.get(code), until));
    }
  }

  // The keys held and confirmed now; a flying key no longer confirmed is let go of.
  confirmed() {
    const now = performance.now();
    const keys = new Set();
    for (const [code, until] of this.held) {
      if (until >= now) keys.add(code);
      else if (!DEADMAN_KEYS.includes(code)) {
        this.held.delete(code);
        this.lapsedKeys.add(code);
      }
    }
    return keys;
  }

  input() {
    const keys = this.confirmed();
    const has = (...codes) => codes.some((code) => keys.has(code));
    const ahead = (has("KeyW", "ArrowUp") ? 1 : 0) - (has("KeyS", "ArrowDown") ? 1 : 0);
    const right = (has("KeyD", "ArrowRight") ? 1 : 0) - (has("KeyA", "ArrowLeft") ? 1 : 0);
    const up = (has("KeyR") ? 1 : 0) - (has("KeyF") ? 1 : 0);
    const moving = ahead !== 0 || right !== 0;
    return {
      deadman: has(...DEADMAN_KEYS),
      direction_deg: moving ? Math.round((Math.atan2(right, ahead) * 180) / Math.PI + 360) % 360 : 0,
      power_percent: moving ? this.powerPercent : 0,
      vertical_percent: up * Math.min(100, this.powerPercent),
    };
  }
}
