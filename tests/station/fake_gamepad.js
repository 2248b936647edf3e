// A fake Gamepad API for the browser tests (and the latency benchmark), added before the page
// loads: navigator.getGamepads() returns the pads the test sets up with window.fakePads.
(() => {
  const pads = [];
  const makeButtons = () => Array.from({ length: 17 }, () => ({ pressed: false, touched: false, value: 0 }));
  function makePad(index, id, mapping) {
    return {
      id, index, mapping, connected: true, frozen: false, frozenAt: 0,
      axes: [0, 0, 0, 0], buttons: makeButtons(), vibrationActuator: null,
      get timestamp() { return this.frozen ? this.frozenAt : performance.now(); },
    };
  }
  window.fakePads = {
    connect(id = "Fake Xbox pad (STANDARD GAMEPAD)", mapping = "standard") {
      const pad = makePad(pads.length, id, mapping);
      pads.push(pad);
      dispatchEvent(Object.assign(new Event("gamepadconnected"), { gamepad: pad }));
      return pad.index;
    },
    disconnect(index) {
      const pad = pads[index];
      pad.connected = false;
      pads[index] = null;
      dispatchEvent(Object.assign(new Event("gamepaddisconnected"), { gamepad: pad }));
    },
    set(index, { axes, buttons } = {}) {
      const pad = pads[index];
      if (axes) axes.forEach((value, i) => { pad.axes[i] = value; });
      if (buttons) {
        for (const [button, down] of Object.entries(buttons)) {
          pad.buttons[Number(button)] = { pressed: down, touched: down, value: down ? 1 : 0 };
        }
      }
      pad.lastSetAt = performance.now();
      return pad.lastSetAt;
    },
    freeze(index) { const pad = pads[index]; pad.frozenAt = pad.timestamp; pad.frozen = true; },
  };
  navigator.getGamepads = () => pads.slice();
})();
