// The gamepad mapping: which axis and button does what. The default is the W3C "standard"
// layout; the pilot may change it and it is saved in this browser (localStorage).

export const ACTIONS = {
  deadman: "dead-man (hold to move)",
  unlock: "unlock (#start!)",
  stop: "STOP (#stop!)",
  claw_open: "claw open (#h+!)",
  claw_close: "claw close (#h-!)",
  mode: "toggle depth / direct mode",
};
export const AXES = {
  strafe: "left/right (+ right)",
  surge: "ahead/astern (+ ahead)",
  vertical: "vertical (+ up)",
};

export const DEFAULT_MAPPING = Object.freeze({
  axes: {
    strafe: { index: 0, invert: false },
    surge: { index: 1, invert: true },     // stick forward reads -1
    vertical: { index: 3, invert: true },
  },
  buttons: { deadman: 4, unlock: 0, stop: 1, claw_open: 2, claw_close: 3, mode: 9 },
  deadzone: 0.12,
});

const KEY = "rovlink.mapping";

export function loadMapping() {
  try {
    const saved = JSON.parse(localStorage.getItem(KEY));
    if (saved && saved.axes && saved.buttons) return validMapping(saved);
  } catch { /* fall through to the default */ }
  return structuredClone(DEFAULT_MAPPING);
}

export function saveMapping(mapping) { localStorage.setItem(KEY, JSON.stringify(mapping)); }

export function resetMapping() { localStorage.removeItem(KEY); return structuredClone(DEFAULT_MAPPING); }

function validMapping(saved) {
  const mapping = structuredClone(DEFAULT_MAPPING);
  for (const name of Object.keys(AXES)) {
    const axis = saved.axes[name];
    if (axis && Number.isInteger(axis.index) && axis.index >= 0) {
      mapping.axes[name] = { index: axis.index, invert: Boolean(axis.invert) };
    }
  }
  for (const name of Object.keys(ACTIONS)) {
    const index = saved.buttons[name];
    if (Number.isInteger(index) && index >= 0) mapping.buttons[name] = index;
  }
  if (typeof saved.deadzone === "number" && saved.deadzone >= 0 && saved.deadzone < 0.9) {
    mapping.deadzone = saved.deadzone;
  }
  return mapping;
}

function shaped(value, deadzone) {
  const size = Math.abs(value);
  if (size <= deadzone) return 0;
  return Math.sign(value) * Math.min(1, (size - deadzone) / (1 - deadzone));
}

function axis(pad, spec) {
  const value = pad.axes[spec.index] ?? 0;
  return spec.invert ? -value : value;
}

export function pressed(pad, index) {
  const button = pad.buttons[index];
  return Boolean(button && (button.pressed || button.value > 0.5));
}

// The pilot's input from a pad: direction clockwise from the bow (stick forward = 0°,
// right = 90°), power = deflection, vertical = the right stick (+ up).
export function padInput(pad, mapping) {
  const x = axis(pad, mapping.axes.strafe);
  const y = axis(pad, mapping.axes.surge);
  const magnitude = shaped(Math.min(1, Math.hypot(x, y)), mapping.deadzone);
  const power = Math.round(magnitude * 100);
  let direction = 0;
  if (power > 0) direction = Math.round((Math.atan2(x, y) * 180) / Math.PI + 360) % 360;
  const vertical = Math.round(shaped(axis(pad, mapping.axes.vertical), mapping.deadzone) * 100);
  return {
    deadman: pressed(pad, mapping.buttons.deadman),
    direction_deg: direction,
    power_percent: power,
    vertical_percent: vertical,
  };
}
