// The leak alarm's sound: a two-tone beep every second until silenced or the latch clears.
// Browsers allow sound only after the person has interacted with the page.

export class AlarmSound {
  constructor() {
    this.context = null;
    this.timer = null;
    const unlock = () => {
      if (!this.context) {
        try { this.context = new AudioContext(); } catch { this.context = null; }
      }
    };
    addEventListener("pointerdown", unlock, { capture: true });
    addEventListener("keydown", unlock, { capture: true });
  }

  get playing() { return this.timer !== null; }

  // Whether a beep is heard: none before the person interacted with the page (a watcher's
  // screen on the deck that nobody touched, say).
  get audible() { return this.context !== null && this.context.state === "running"; }

  start() {
    if (this.timer !== null) return;
    this.beep();
    this.timer = setInterval(() => this.beep(), 1000);
  }

  stop() {
    if (this.timer !== null) clearInterval(this.timer);
    this.timer = null;
  }

  beep() {
    const context = this.context;
    if (!context) return;
    for (const [offset, frequency] of [[0, 880], [0.25, 660]]) {
      const oscillator = context.createOscillator();
      const gain = context.createGain();
      oscillator.frequency.value = frequency;
      gain.gain.value = 0.2;
      oscillator.connect(gain).connect(context.destination);
      oscillator.start(context.currentTime + offset);
      oscillator.stop(context.currentTime + offset + 0.2);
    }
  }
}
