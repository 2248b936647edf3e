// The pilot's instruments, drawn on canvases: attitude, heading tape, depth gauge, thrust.

const SKY = "#2f7fbf", GROUND = "#7a5530", WHITE = "#ffffff", MUTED = "#8096a7";
const TARGET = "#ffb347", ACCENT = "#4fb3ff", GOOD = "#3ecf7a";

function context(canvas) {
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  return ctx;
}

export function drawAttitude(canvas, rollDeg, pitchDeg) {
  const ctx = context(canvas);
  const { width: w, height: h } = canvas;
  const r = Math.min(w, h) / 2 - 6;
  const pxPerDeg = r / 45;
  ctx.save();
  ctx.translate(w / 2, h / 2);
  ctx.beginPath(); ctx.arc(0, 0, r, 0, 2 * Math.PI); ctx.clip();
  ctx.save();
  ctx.rotate((-(rollDeg ?? 0) * Math.PI) / 180);
  ctx.translate(0, (pitchDeg ?? 0) * pxPerDeg);
  ctx.fillStyle = SKY; ctx.fillRect(-2 * r, -4 * r, 4 * r, 4 * r);
  ctx.fillStyle = GROUND; ctx.fillRect(-2 * r, 0, 4 * r, 4 * r);
  ctx.strokeStyle = WHITE; ctx.fillStyle = WHITE; ctx.lineWidth = 2;
  ctx.beginPath(); ctx.moveTo(-2 * r, 0); ctx.lineTo(2 * r, 0); ctx.stroke();
  ctx.font = "11px sans-serif"; ctx.textAlign = "left"; ctx.textBaseline = "middle";
  ctx.lineWidth = 1;
  for (let deg = -60; deg <= 60; deg += 10) {
    if (deg === 0) continue;
    const y = -deg * pxPerDeg, half = deg % 20 === 0 ? r * 0.3 : r * 0.15;
    ctx.beginPath(); ctx.moveTo(-half, y); ctx.lineTo(half, y); ctx.stroke();
    if (deg % 20 === 0) ctx.fillText(String(deg), half + 4, y);
  }
  ctx.restore();
  // Roll scale and pointer.
  ctx.strokeStyle = WHITE; ctx.lineWidth = 2;
  for (const deg of [-60, -45, -30, -20, -10, 0, 10, 20, 30, 45, 60]) {
    const a = ((deg - 90) * Math.PI) / 180, inner = deg % 30 === 0 ? r - 14 : r - 8;
    ctx.beginPath(); ctx.moveTo(Math.cos(a) * inner, Math.sin(a) * inner);
    ctx.lineTo(Math.cos(a) * r, Math.sin(a) * r); ctx.stroke();
  }
  ctx.rotate((-(rollDeg ?? 0) * Math.PI) / 180);
  ctx.fillStyle = TARGET;
  ctx.beginPath(); ctx.moveTo(0, -r + 16); ctx.lineTo(-7, -r + 28); ctx.lineTo(7, -r + 28); ctx.fill();
  ctx.restore();
  // The vehicle symbol, fixed.
  ctx.save(); ctx.translate(w / 2, h / 2);
  ctx.strokeStyle = TARGET; ctx.lineWidth = 4;
  ctx.beginPath(); ctx.moveTo(-r * 0.55, 0); ctx.lineTo(-r * 0.18, 0); ctx.lineTo(-r * 0.1, 10);
  ctx.moveTo(r * 0.55, 0); ctx.lineTo(r * 0.18, 0); ctx.lineTo(r * 0.1, 10); ctx.stroke();
  ctx.fillStyle = TARGET; ctx.beginPath(); ctx.arc(0, 0, 4, 0, 2 * Math.PI); ctx.fill();
  ctx.strokeStyle = MUTED; ctx.lineWidth = 2; ctx.beginPath(); ctx.arc(0, 0, r, 0, 2 * Math.PI); ctx.stroke();
  if (rollDeg === null || rollDeg === undefined) {
    ctx.fillStyle = "rgba(0,0,0,0.6)"; ctx.fillRect(-r, -12, 2 * r, 24);
    ctx.fillStyle = WHITE; ctx.textAlign = "center"; ctx.font = "13px sans-serif";
    ctx.fillText("no reading", 0, 4);
  }
  ctx.restore();
}

const CARDINALS = { 0: "N", 45: "NE", 90: "E", 135: "SE", 180: "S", 225: "SW", 270: "W", 315: "NW" };

// The heading tape's width at most (px): on a narrower window it is drawn for the width it is
// shown at, not drawn at this width and shrunk with its figures (6 px high on a phone).
const HEADING_WIDTH_PX = 620;

// A label centred on ``x``, drawn only if it fits whole: cut at the tape's edge, "300" read "00".
function label(ctx, text, x, y) {
  const half = ctx.measureText(text).width / 2;
  if (x - half >= 0 && x + half <= ctx.canvas.width) ctx.fillText(text, x, y);
}

export function drawHeading(canvas, headingDeg) {
  const shownPx = Math.floor(canvas.parentElement?.clientWidth ?? HEADING_WIDTH_PX);
  const widthPx = Math.min(HEADING_WIDTH_PX, shownPx > 0 ? shownPx : HEADING_WIDTH_PX);
  if (canvas.width !== widthPx) canvas.width = widthPx;
  const ctx = context(canvas);
  const { width: w, height: h } = canvas;
  const pxPerDeg = w / 120;
  ctx.fillStyle = "#0f1920"; ctx.fillRect(0, 0, w, h);
  if (headingDeg === null || headingDeg === undefined) {
    // No scale: round north, it would read as a heading.
    ctx.fillStyle = MUTED; ctx.textAlign = "center"; ctx.font = "13px sans-serif";
    ctx.fillText("no reading", w / 2, h / 2 + 4);
    return;
  }
  const heading = headingDeg;
  ctx.strokeStyle = WHITE; ctx.fillStyle = WHITE; ctx.textAlign = "center";
  ctx.font = "12px sans-serif";
  const first = Math.ceil((heading - 60) / 5) * 5;
  for (let deg = first; deg <= heading + 60; deg += 5) {
    const x = w / 2 + (deg - heading) * pxPerDeg;
    const norm = ((deg % 360) + 360) % 360;
    const long = norm % 15 === 0;
    ctx.beginPath(); ctx.moveTo(x, h); ctx.lineTo(x, h - (long ? 18 : 9)); ctx.stroke();
    if (norm % 45 === 0) {
      ctx.font = "bold 14px sans-serif"; label(ctx, CARDINALS[norm], x, h - 26);
    } else if (norm % 15 === 0) {
      ctx.font = "11px sans-serif"; label(ctx, String(norm), x, h - 26);
    }
  }
  ctx.fillStyle = TARGET;
  ctx.beginPath(); ctx.moveTo(w / 2 - 8, 0); ctx.lineTo(w / 2 + 8, 0); ctx.lineTo(w / 2, 12); ctx.fill();
  ctx.fillStyle = "#000"; ctx.fillRect(w / 2 - 24, 12, 48, 18);
  ctx.fillStyle = WHITE; ctx.font = "bold 13px sans-serif";
  ctx.fillText(`${heading}°`, w / 2, 26);
}

export function drawDepth(canvas, depthCm, targetCm) {
  const ctx = context(canvas);
  const { width: w, height: h } = canvas;
  const top = 14, bottom = h - 14;
  const highest = Math.max(200, (depthCm ?? 0) * 1.3, (targetCm ?? 0) * 1.3);
  const span = Math.ceil(highest / 100) * 100;
  const y = (cm) => top + (Math.min(cm, span) / span) * (bottom - top);
  const grad = ctx.createLinearGradient(0, top, 0, bottom);
  grad.addColorStop(0, "#1f6fa6"); grad.addColorStop(1, "#06223a");
  ctx.fillStyle = grad; ctx.fillRect(40, top, 30, bottom - top);
  ctx.strokeStyle = MUTED; ctx.fillStyle = MUTED; ctx.font = "11px sans-serif"; ctx.textAlign = "right";
  const step = span <= 400 ? 50 : span <= 1000 ? 100 : 500;
  for (let cm = 0; cm <= span; cm += step) {
    ctx.beginPath(); ctx.moveTo(34, y(cm)); ctx.lineTo(40, y(cm)); ctx.stroke();
    ctx.fillText(String(cm), 32, y(cm) + 4);
  }
  if (targetCm !== null && targetCm !== undefined) {
    ctx.strokeStyle = TARGET; ctx.lineWidth = 2; ctx.setLineDash([5, 3]);
    ctx.beginPath(); ctx.moveTo(36, y(targetCm)); ctx.lineTo(w - 4, y(targetCm)); ctx.stroke();
    ctx.setLineDash([]); ctx.fillStyle = TARGET; ctx.textAlign = "left";
    const crowded = depthCm !== null && depthCm !== undefined && Math.abs(y(targetCm) - y(depthCm)) < 16;
    ctx.fillText(`target ${targetCm}`, 72, y(targetCm) + (crowded && targetCm > depthCm ? 14 : -5));
  }
  if (depthCm !== null && depthCm !== undefined) {
    ctx.fillStyle = ACCENT;
    ctx.beginPath(); ctx.moveTo(72, y(depthCm)); ctx.lineTo(84, y(depthCm) - 7);
    ctx.lineTo(84, y(depthCm) + 7); ctx.fill();
    ctx.fillStyle = WHITE; ctx.textAlign = "left"; ctx.font = "bold 12px sans-serif";
    ctx.fillText(String(depthCm), 86, y(depthCm) + (targetCm !== null && targetCm !== undefined
      && Math.abs(y(targetCm) - y(depthCm)) < 16 && targetCm <= depthCm ? 14 : 4));
  }
}

// The thrust as last sent (arrow) and the pilot's stick now (thin line), bow up;
// the bar on the right is vertical thrust (direct mode).
export function drawThrust(canvas, commanded, stick) {
  const ctx = context(canvas);
  const { width: w, height: h } = canvas;
  const cx = (w - 40) / 2, cy = h / 2, r = Math.min(cx, cy) - 10;
  ctx.strokeStyle = MUTED; ctx.lineWidth = 1;
  for (const f of [0.5, 1]) { ctx.beginPath(); ctx.arc(cx, cy, r * f, 0, 2 * Math.PI); ctx.stroke(); }
  ctx.fillStyle = MUTED; ctx.font = "11px sans-serif"; ctx.textAlign = "center";
  ctx.fillText("bow", cx, cy - r - 1);
  // The hull.
  ctx.strokeStyle = WHITE; ctx.lineWidth = 2;
  ctx.strokeRect(cx - 12, cy - 20, 24, 40);
  const arrow = (directionDeg, fraction, colour, width) => {
    const a = ((directionDeg - 90) * Math.PI) / 180;
    const x = cx + Math.cos(a) * r * fraction, y = cy + Math.sin(a) * r * fraction;
    ctx.strokeStyle = colour; ctx.fillStyle = colour; ctx.lineWidth = width;
    ctx.beginPath(); ctx.moveTo(cx, cy); ctx.lineTo(x, y); ctx.stroke();
    ctx.beginPath(); ctx.arc(x, y, width + 2, 0, 2 * Math.PI); ctx.fill();
  };
  if (stick && stick.power_percent > 0) arrow(stick.direction_deg, stick.power_percent / 100, ACCENT, 1);
  if (commanded && commanded.power_percent > 0) {
    arrow(commanded.direction_deg, commanded.power_percent / 100, GOOD, 4);
  }
  const barX = w - 26, barTop = cy - r, barH = 2 * r;
  ctx.strokeStyle = MUTED; ctx.lineWidth = 1; ctx.strokeRect(barX, barTop, 14, barH);
  ctx.beginPath(); ctx.moveTo(barX - 3, cy); ctx.lineTo(barX + 17, cy); ctx.stroke();
  const vertical = commanded && commanded.vertical_mode === "direct" ? commanded.vertical_thrust_percent : 0;
  if (vertical) {
    ctx.fillStyle = GOOD;
    const size = (Math.abs(vertical) / 100) * r;
    ctx.fillRect(barX + 1, vertical > 0 ? cy - size : cy, 12, size);
  }
}
