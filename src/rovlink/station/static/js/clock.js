// The clock the page stamps what it sends with (`sent_ms`): steady as performance.now(), and
// counting the time the computer slept, which performance.now() does not count in Chrome on
// Linux and macOS. The station measures how late each message arrives against the fastest
// one: stamped with a clock that stood still while the computer slept, every message after it
// would seem that much later, for good, and the pilot could not fly again on that connection.

// The wall clock ran ahead of the steady clock by more than this between two looks: the
// computer slept. Well under the 300 ms an input may arrive late, and well over the two
// clocks' jitter (a wall clock NTP slews drifts 0.05 % at most). A wall clock set forward by
// hand or by NTP counts as well, harmlessly: what is sent then only seems early.
const ASLEEP_MS = 100;
const LOOK_MS = 250;

let asleepMs = 0;
let lookedAt = { steadyMs: performance.now(), wallMs: Date.now() };

function look() {
  const now = { steadyMs: performance.now(), wallMs: Date.now() };
  const lostMs = (now.wallMs - lookedAt.wallMs) - (now.steadyMs - lookedAt.steadyMs);
  if (lostMs > ASLEEP_MS) asleepMs += lostMs;
  lookedAt = now;
}
setInterval(look, LOOK_MS);

// Now, in ms, for a message's `sent_ms`.
export function stampMs() {
  look();  // (a message sent on waking, before the next look, counts the sleep too)
  return performance.now() + asleepMs;
}
