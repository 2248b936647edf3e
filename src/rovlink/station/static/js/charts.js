// Live charts with uPlot (vendored): depth against its target, and attitude.

const WINDOW_S = 300;

// As wide as its panel (a 320 px phone's too: the page never scrolls sideways), and no narrower
// than its axes and a few ticks need.
function sizeOf(element) { return { width: Math.max(200, element.clientWidth - 4), height: 180 }; }

function series(label, stroke, extra = {}) {
  return { label, stroke, width: 1.5, spanGaps: false, points: { show: false }, ...extra };
}

export class Charts {
  constructor(depthElement, attitudeElement) {
    this.columns = [[], [], [], [], [], []];   // t, depth, target, roll, pitch, heading
    const axisStyle = { stroke: "#8096a7", grid: { stroke: "#22313c" }, ticks: { stroke: "#22313c" } };
    this.depth = new uPlot({
      ...sizeOf(depthElement),
      scales: { x: { time: false }, y: { dir: -1, range: (u, min, max) => [0, Math.max(100, max * 1.1)] } },
      axes: [{ ...axisStyle, label: "s" }, { ...axisStyle, label: "cm" }],
      series: [{ label: "t (s)" }, series("depth (cm)", "#4fb3ff"),
        series("target (cm)", "#ffb347", { dash: [6, 4] })],
      legend: { live: false },
    }, [[], [], []], depthElement);
    this.attitude = new uPlot({
      ...sizeOf(attitudeElement),
      scales: { x: { time: false }, deg: { range: [-90, 90] }, hdg: { range: [0, 360] } },
      axes: [{ ...axisStyle, label: "s" }, { ...axisStyle, scale: "deg", label: "roll, pitch (°)" },
        { ...axisStyle, scale: "hdg", side: 1, label: "heading (°)", grid: { show: false } }],
      series: [{ label: "t (s)" }, series("roll (°)", "#3ecf7a", { scale: "deg" }),
        series("pitch (°)", "#e26dff", { scale: "deg" }),
        series("heading (°)", "#8096a7", { scale: "hdg", width: 1 })],
      legend: { live: false },
    }, [[], [], [], []], attitudeElement);
    this.dirty = false;
    addEventListener("resize", () => {
      this.depth.setSize(sizeOf(depthElement));
      this.attitude.setSize(sizeOf(attitudeElement));
    });
    // Redraw at most a few times a second, whatever the telemetry rate.
    setInterval(() => this.redraw(), 250);
  }

  clear() {
    this.columns.forEach((column) => { column.length = 0; });
    this.dirty = true;
  }

  add(row) {
    row.forEach((value, i) => this.columns[i].push(value));
    const oldest = row[0] - WINDOW_S;
    while (this.columns[0].length && this.columns[0][0] < oldest) this.columns.forEach((c) => c.shift());
    this.dirty = true;
  }

  redraw() {
    if (!this.dirty || document.hidden) return;
    this.dirty = false;
    const [t, depth, target, roll, pitch, heading] = this.columns;
    this.depth.setData([t, depth, target]);
    this.attitude.setData([t, roll, pitch, heading]);
  }
}
