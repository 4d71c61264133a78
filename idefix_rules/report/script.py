"""The report page's own script: the interactive result map and the run panel (no library).

About 400 lines of plain JavaScript on ``<canvas>``: the page stays one small offline file that
any browser opens from disk, under a Content-Security-Policy that forbids every request. It reads
the JSON of :mod:`.interactive` from ``<script id="report-data" type="application/json">``.

- Map: cells coloured by risk (mean of run maxima over the paths switched on, the paper's
  Fig. 8 rule), obstacles with level and buffer, each path's ideal (commanded) path dashed, its
  reference run solid with the four wheel tracks, first contacts as crosses.
- Hover a cell: its risk (in %), and per path the runs that crossed it and their dominant
  index. Axes in metres along the left and bottom edges, and a scale bar.
- Wheel footprints only for one path at a time (the open run's, or the only path switched on):
  every path's at once hide the map.
- Checkboxes switch paths on and off. A click on a cell, or on a row of a worst-runs table,
  opens that run: its track and wheel footprints on the map, its time series against the
  rulebook's limits.
- A worst-case search's page (a path's ``worst`` in the JSON) draws each path's worst run
  dotted over a white halo, with a dot at its end and a label (path, run, I_max) moved down
  until it overlaps no other; hovering the label explains it, a click on it opens the run.
"""

CSS = """
.imap { position: relative; }
.imap canvas { width: 100%; display: block; border: 1px solid #e3e7ec; cursor: crosshair; }
.imap .tip { position: absolute; pointer-events: none; background: rgba(29,35,42,.92);
  color: #fff; font-size: 12.5px; padding: 6px 9px; border-radius: 4px; max-width: 340px;
  display: none; z-index: 2; line-height: 1.35; }
.legend { display: flex; flex-wrap: wrap; gap: 6px 16px; font-size: 0.9em; margin: 8px 0; }
.legend label { white-space: nowrap; cursor: pointer; }
.legend .swatch { display: inline-block; width: 22px; height: 4px; vertical-align: middle;
  margin-right: 4px; }
.scale { display: flex; align-items: center; gap: 8px; font-size: 0.88em; margin: 4px 0; }
.scale .bar { flex: 0 1 240px; height: 12px;
  background: linear-gradient(90deg, #1a9850, #91cf60, #fee08b, #fc8d59, #d73027); }
.runpanel { display: none; border-top: 2px solid #1d2b3a; margin-top: 12px; padding-top: 8px; }
.runpanel .charts { display: grid; grid-template-columns: repeat(auto-fill, minmax(300px, 1fr));
  gap: 10px; }
.runpanel canvas { width: 100%; height: 150px; border: 1px solid #e3e7ec; }
tr.run { cursor: pointer; } tr.run:hover { background: #eef4ff; }
"""

SCRIPT = r"""
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("report-data").textContent);
  var root = document.getElementById("imap");
  if (!root) { return; }
  var canvas = root.querySelector("canvas"), tip = root.querySelector(".tip");
  var panel = document.getElementById("runpanel");
  var on = {}, selected = null, g = data.grid, view = null, marks = [];
  var LEVEL = {L1: "#1f77b4", L2: "#ff7f0e", L3: "#d62728"};
  var STOPS = [[26, 152, 80], [145, 207, 96], [254, 224, 139], [252, 141, 89], [215, 48, 39]];
  data.paths.forEach(function (p) { on[p.name] = true; });

  function colour(risk) {
    var v = Math.max(0, Math.min(1, risk)) * (STOPS.length - 1), i = Math.min(
      Math.floor(v), STOPS.length - 2), f = v - i, a = STOPS[i], b = STOPS[i + 1];
    return "rgb(" + [0, 1, 2].map(function (k) {
      return Math.round(a[k] + f * (b[k] - a[k])); }).join(",") + ")";
  }
  function title(name) {
    var info = data.indices[name];
    return name + (info && info.title ? " (" + info.title + ")" : "");
  }
  function cellTable() {
    var cells = {};
    data.paths.forEach(function (p) {
      if (!on[p.name] || !p.cells) { return; }
      p.cells.forEach(function (c) {
        var e = cells[c[0]] || (cells[c[0]] = {total: 0, runs: 0, per: []});
        e.total += c[1]; e.runs += c[2];
        e.per.push({path: p.name, runs: c[2], dominant: c[3], count: c[4], worst: c[5],
                    mean: c[1] / c[2]});
      });
    });
    return cells;
  }
  var AXIS_LEFT = 46, AXIS_BOTTOM = 34, AXIS_PAD = 8;  // px kept for the axes in metres
  var axes = {x: [], y: [], scale: ""};
  function setup() {
    var width = root.clientWidth, ratio = window.devicePixelRatio || 1;
    var worldW = g.nx * g.cell, worldH = g.ny * g.cell;
    var plotW = Math.max(40, width - AXIS_LEFT - AXIS_PAD);
    var height = Math.max(160, Math.min(plotW * worldH / worldW + AXIS_BOTTOM + AXIS_PAD, 900));
    var scale = Math.min(plotW / worldW, (height - AXIS_BOTTOM - AXIS_PAD) / worldH);
    canvas.style.height = height + "px";
    canvas.width = Math.round(width * ratio); canvas.height = Math.round(height * ratio);
    view = {scale: scale, ratio: ratio, ox: AXIS_LEFT + (plotW - worldW * scale) / 2,
            oy: AXIS_BOTTOM + (height - AXIS_BOTTOM - AXIS_PAD - worldH * scale) / 2,
            height: height, width: width};
  }
  function niceStep(span, count) {  // 1, 2 or 5 × 10^k, about `count` steps over `span`
    var raw = span / Math.max(count, 1), power = Math.pow(10, Math.floor(Math.log10(raw)));
    var steps = [1, 2, 5, 10];
    for (var i = 0; i < steps.length; i++) {
      if (steps[i] * power >= raw) { return steps[i] * power; }
    }
    return 10 * power;
  }
  function label(value, step) {
    return value.toFixed(Math.max(0, -Math.floor(Math.log10(step) + 1e-9)));
  }
  function drawAxes(ctx) {  // ticks in metres on the left and bottom, and a scale bar
    var x0 = g.x0, x1 = g.x0 + g.nx * g.cell, y0 = g.y0, y1 = g.y0 + g.ny * g.cell;
    var left = sx(x0), right = sx(x1), bottom = sy(y0), top = sy(y1);
    ctx.strokeStyle = "#66707a"; ctx.fillStyle = "#3b444d"; ctx.lineWidth = 1;
    ctx.font = "11px system-ui, sans-serif";
    ctx.strokeRect(left, top, right - left, bottom - top);
    axes = {x: [], y: [], scale: ""};
    var step = niceStep(x1 - x0, Math.max(2, (right - left) / 90));
    ctx.textAlign = "center"; ctx.textBaseline = "top";
    for (var x = Math.ceil(x0 / step) * step; x <= x1 + 1e-9; x += step) {
      ctx.beginPath(); ctx.moveTo(sx(x), bottom); ctx.lineTo(sx(x), bottom + 4); ctx.stroke();
      ctx.fillText(label(x, step), sx(x), bottom + 5); axes.x.push(label(x, step));
    }
    ctx.fillText("x [m]", (left + right) / 2, bottom + 19);
    step = niceStep(y1 - y0, Math.max(2, (bottom - top) / 60));
    ctx.textAlign = "right"; ctx.textBaseline = "middle";
    for (var y = Math.ceil(y0 / step) * step; y <= y1 + 1e-9; y += step) {
      ctx.beginPath(); ctx.moveTo(left, sy(y)); ctx.lineTo(left - 4, sy(y)); ctx.stroke();
      ctx.fillText(label(y, step), left - 6, sy(y)); axes.y.push(label(y, step));
    }
    ctx.save(); ctx.translate(11, (top + bottom) / 2); ctx.rotate(-Math.PI / 2);
    ctx.textAlign = "center"; ctx.fillText("y [m]", 0, 0); ctx.restore();
    // scale bar: a round length near a fifth of the plot's width, in its top right corner
    var length = niceStep((x1 - x0) / 5, 1), bar = length * view.scale;
    var bx = right - 10 - bar, by = top + 14;
    ctx.fillStyle = "rgba(255,255,255,.8)"; ctx.fillRect(bx - 6, by - 12, bar + 12, 22);
    ctx.strokeStyle = "#1d232a"; ctx.lineWidth = 2; ctx.beginPath();
    ctx.moveTo(bx, by - 4); ctx.lineTo(bx, by + 4); ctx.moveTo(bx, by); ctx.lineTo(bx + bar, by);
    ctx.moveTo(bx + bar, by - 4); ctx.lineTo(bx + bar, by + 4); ctx.stroke();
    axes.scale = (length >= 1 ? label(length, length) + " m"
                  : Math.round(length * 100) + " cm");
    ctx.fillStyle = "#1d232a"; ctx.textAlign = "center"; ctx.textBaseline = "bottom";
    ctx.fillText(axes.scale, bx + bar / 2, by - 3); ctx.textBaseline = "alphabetic";
  }
  function percent(risk) { return (100 * risk).toFixed(1) + " %"; }
  function focus() {  // the path whose wheel footprints are drawn: the open run's, else the
    if (selected) { return selected.path; }  // one path switched on, else none (clutter)
    var shown = data.paths.filter(function (p) { return on[p.name]; });
    return shown.length === 1 ? shown[0].name : null;
  }
  function sx(x) { return view.ox + (x - g.x0) * view.scale; }
  function sy(y) { return view.height - view.oy - (y - g.y0) * view.scale; }
  function line(ctx, xs, ys, style, width, dash) {
    if (!xs || xs.length < 2) { return; }
    ctx.beginPath(); ctx.setLineDash(dash || []); ctx.strokeStyle = style;
    ctx.lineWidth = width;
    var started = false;
    for (var i = 0; i < xs.length; i++) {
      if (xs[i] === null || ys[i] === null) { started = false; continue; }
      if (started) { ctx.lineTo(sx(xs[i]), sy(ys[i])); }
      else { ctx.moveTo(sx(xs[i]), sy(ys[i])); started = true; }
    }
    ctx.stroke(); ctx.setLineDash([]);
  }
  function wheelsOf(run) {
    var out = {FL: [[], []], FR: [[], []], RL: [[], []], RR: [[], []]};
    var a = data.rover.half_wheelbase, b = data.rover.half_track;
    var off = {FL: [a, b], FR: [a, -b], RL: [-a, b], RR: [-a, -b]};
    if (!run.yaw) { return null; }
    for (var i = 0; i < run.x.length; i++) {
      if (run.x[i] === null || run.yaw[i] === null) { continue; }
      var c = Math.cos(run.yaw[i]), s = Math.sin(run.yaw[i]);
      Object.keys(off).forEach(function (w) {
        out[w][0].push(run.x[i] + off[w][0] * c - off[w][1] * s);
        out[w][1].push(run.y[i] + off[w][0] * s + off[w][1] * c);
      });
    }
    return out;
  }
  function draw() {
    setup();
    var ctx = canvas.getContext("2d");
    ctx.setTransform(view.ratio, 0, 0, view.ratio, 0, 0);
    ctx.clearRect(0, 0, canvas.width, canvas.height);
    ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, canvas.width, canvas.height);
    var cells = cellTable(), size = g.cell * view.scale + 0.5;
    Object.keys(cells).forEach(function (k) {
      var e = cells[k], col = k % g.nx, row = Math.floor(k / g.nx);
      ctx.fillStyle = colour(e.total / e.runs);
      ctx.fillRect(sx(g.x0 + col * g.cell), sy(g.y0 + (row + 1) * g.cell), size, size);
    });
    data.areas.forEach(function (a) {
      ctx.beginPath();
      a.polygon.forEach(function (p, i) {
        if (i) { ctx.lineTo(sx(p[0]), sy(p[1])); } else { ctx.moveTo(sx(p[0]), sy(p[1])); }
      });
      ctx.closePath(); ctx.fillStyle = "rgba(127,127,127,.25)"; ctx.fill();
      ctx.strokeStyle = LEVEL[a.level] || "#777"; ctx.lineWidth = 1.5; ctx.stroke();
    });
    data.rocks.forEach(function (r) {
      var c = LEVEL[r.level] || "#777";
      ctx.beginPath();
      ctx.ellipse(sx(r.x), sy(r.y), r.a * view.scale, r.b * view.scale, 0, 0, 2 * Math.PI);
      ctx.fillStyle = "#8d8d8d"; ctx.fill(); ctx.strokeStyle = c; ctx.lineWidth = 2;
      ctx.stroke();
      if (r.buffer > 0) {
        ctx.beginPath(); ctx.setLineDash([5, 4]);
        ctx.ellipse(sx(r.x), sy(r.y), (r.a + r.buffer) * view.scale,
                    (r.b + r.buffer) * view.scale, 0, 0, 2 * Math.PI);
        ctx.stroke(); ctx.setLineDash([]);
      }
      ctx.fillStyle = c; ctx.font = "13px system-ui, sans-serif"; ctx.textAlign = "center";
      ctx.fillText(r.name + " " + r.level + (r.buffer > 0 ? " · buffer " +
        Math.round(r.buffer * 100) + " cm" : ""), sx(r.x), sy(r.y + r.b + r.buffer) - 5);
    });
    var focused = focus();
    data.paths.forEach(function (p) {
      if (!on[p.name]) { return; }
      if (p.wheels && p.name === focused) {
        Object.keys(p.wheels).forEach(function (w) {  // footprint band, then its centre
          line(ctx, p.wheels[w][0], p.wheels[w][1], p.colour + "30",
               Math.max(1, data.rover.wheel_width * view.scale));
          line(ctx, p.wheels[w][0], p.wheels[w][1], p.colour + "88", 1);
        });
      }
      if (p.ideal) { line(ctx, p.ideal[0], p.ideal[1], p.colour, 1.8, [7, 5]); }
      if (p.reference) { line(ctx, p.reference[0], p.reference[1], p.colour, 2.4); }
      (p.contacts || []).forEach(function (c) {
        var x = sx(c.x), y = sy(c.y);
        ctx.strokeStyle = "#000"; ctx.lineWidth = 1.5; ctx.beginPath();
        ctx.moveTo(x - 4, y - 4); ctx.lineTo(x + 4, y + 4);
        ctx.moveTo(x - 4, y + 4); ctx.lineTo(x + 4, y - 4); ctx.stroke();
      });
    });
    marks = [];
    data.paths.forEach(function (p) {  // a worst-case search's worst run of each path
      var run = p.worst === undefined ? null : p.runs[String(p.worst)];
      if (!on[p.name] || !run) { return; }
      line(ctx, run.x, run.y, "rgba(255,255,255,.85)", 4.6);
      line(ctx, run.x, run.y, p.colour, 2.4, [2, 3]);
      for (var i = run.x.length - 1; i >= 0; i--) {
        if (run.x[i] !== null && run.y[i] !== null) {
          marks.push({path: p.name, run: p.worst, colour: p.colour, x: sx(run.x[i]),
                      y: sy(run.y[i]), text: p.name + " · worst run " + p.worst + " · I_max " +
                      percent(run.i_max)});
          break;
        }
      }
    });
    if (selected) {
      var wheels = wheelsOf(selected.run);
      if (wheels) {
        Object.keys(wheels).forEach(function (w) {
          line(ctx, wheels[w][0], wheels[w][1], "rgba(0,0,0,.18)",
               Math.max(1, data.rover.wheel_width * view.scale));
          line(ctx, wheels[w][0], wheels[w][1], "rgba(0,0,0,.55)", 1.2);
        });
      }
      line(ctx, selected.run.x, selected.run.y, "#000", 3);
    }
    drawAxes(ctx);
    labelMarks(ctx);
  }
  function labelMarks(ctx) {  // each worst run's end: a dot, and a label that hides no other
    ctx.font = "12px system-ui, sans-serif"; ctx.textAlign = "left";
    ctx.textBaseline = "middle";
    var placed = [];
    marks.forEach(function (m) {
      var w = ctx.measureText(m.text).width + 10, h = 18;
      var left = Math.max(AXIS_LEFT + 2, Math.min(m.x + 10, view.width - AXIS_PAD - w));
      var top = Math.max(2, m.y - h - 6);
      for (var tries = 0; tries < 40 && placed.some(function (b) {
        return left < b.left + b.w && b.left < left + w && top < b.top + b.h &&
          b.top < top + h; }); tries++) { top += h + 3; }
      m.box = {left: left, top: top, w: w, h: h};
      placed.push(m.box);
      ctx.strokeStyle = m.colour; ctx.lineWidth = 1; ctx.setLineDash([]);
      ctx.beginPath(); ctx.moveTo(m.x, m.y);
      ctx.lineTo(Math.max(left, Math.min(m.x, left + w)), top + h / 2); ctx.stroke();
      ctx.fillStyle = "rgba(255,255,255,.92)"; ctx.fillRect(left, top, w, h);
      ctx.lineWidth = 1.5; ctx.strokeRect(left, top, w, h);
      ctx.fillStyle = "#1d232a"; ctx.fillText(m.text, left + 5, top + h / 2 + 0.5);
      ctx.beginPath(); ctx.arc(m.x, m.y, 4.5, 0, 2 * Math.PI); ctx.fillStyle = m.colour;
      ctx.fill(); ctx.strokeStyle = "#000"; ctx.lineWidth = 1.2; ctx.stroke();
    });
    ctx.textBaseline = "alphabetic";
  }
  function markAt(event) {  // the worst-run label (or end dot) under the mouse, if any
    var box = canvas.getBoundingClientRect();
    var px = event.clientX - box.left, py = event.clientY - box.top;
    for (var i = marks.length - 1; i >= 0; i--) {
      var m = marks[i], b = m.box;
      if ((b && px >= b.left - 2 && px <= b.left + b.w + 2 && py >= b.top - 2 &&
           py <= b.top + b.h + 2) || Math.hypot(px - m.x, py - m.y) <= 7) {
        return {mark: m, px: px, py: py};
      }
    }
    return null;
  }
  function cellAt(event) {
    var box = canvas.getBoundingClientRect();
    var x = g.x0 + (event.clientX - box.left - view.ox) / view.scale;
    var y = g.y0 + (view.height - (event.clientY - box.top) - view.oy) / view.scale;
    var col = Math.floor((x - g.x0) / g.cell), row = Math.floor((y - g.y0) / g.cell);
    if (col < 0 || row < 0 || col >= g.nx || row >= g.ny) { return null; }
    return {key: row * g.nx + col, x: x, y: y, px: event.clientX - box.left,
            py: event.clientY - box.top};
  }
  function text(s) { var d = document.createElement("div"); d.textContent = s;
    return d.innerHTML; }
  canvas.addEventListener("mousemove", function (event) {
    var hit = markAt(event);
    canvas.style.cursor = hit ? "pointer" : "";
    if (hit) {
      tip.innerHTML = "<b>" + text(hit.mark.text) + "</b><br>the highest run risk the " +
        "worst-case search found on this path<br><i>click: open this run</i>";
      tip.style.display = "block";
      tip.style.left = Math.min(hit.px + 14, root.clientWidth - tip.offsetWidth - 4) + "px";
      tip.style.top = (hit.py + 14) + "px";
      return;
    }
    var at = cellAt(event), cells = cellTable(), e = at && cells[at.key];
    if (!e) { tip.style.display = "none"; return; }
    var html = "<b>risk " + percent(e.total / e.runs) + "</b> · " + e.runs +
      " run(s) · x " + at.x.toFixed(2) + " m, y " + at.y.toFixed(2) + " m";
    e.per.forEach(function (p) {
      html += "<br>" + text(p.path) + ": " + p.runs + " run(s), risk " + percent(p.mean) +
        (p.dominant ? ", dominant " + text(title(p.dominant)) + " in " + p.count : "");
    });
    tip.innerHTML = html + "<br><i>click: open the worst run here</i>";
    tip.style.display = "block";
    tip.style.left = Math.min(at.px + 14, root.clientWidth - tip.offsetWidth - 4) + "px";
    tip.style.top = (at.py + 14) + "px";
  });
  canvas.addEventListener("mouseleave", function () { tip.style.display = "none"; });
  canvas.addEventListener("click", function (event) {
    var hit = markAt(event);
    if (hit) { openRun(hit.mark.path, hit.mark.run); return; }
    var at = cellAt(event), cells = cellTable(), e = at && cells[at.key];
    if (!e) { return; }
    var best = null;
    e.per.forEach(function (p) {
      if (p.worst >= 0 && (!best || p.mean > best.mean)) { best = p; }
    });
    if (best) { openRun(best.path, best.worst); }
  });
  function chart(el, t, values, limit, unit, name) {
    var box = el.getBoundingClientRect(), ratio = window.devicePixelRatio || 1;
    el.width = Math.round(box.width * ratio); el.height = Math.round(box.height * ratio);
    var ctx = el.getContext("2d"), w = box.width, h = box.height, L = 46, B = 22, T = 18;
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    var finite = values.filter(function (v) { return v !== null; });
    var hi = Math.max.apply(null, finite.concat([limit === null ? 0 : limit * 1.1, 1e-9]));
    var lo = Math.min.apply(null, finite.concat([0]));
    var t1 = t[t.length - 1] || 1;
    function px(x) { return L + (x / t1) * (w - L - 8); }
    function py(v) { return T + (1 - (v - lo) / (hi - lo || 1)) * (h - T - B); }
    ctx.font = "12px system-ui, sans-serif"; ctx.fillStyle = "#1d232a";
    ctx.fillText(name + " [" + unit + "]", L, 12);
    ctx.fillStyle = "#66707a"; ctx.textAlign = "right";
    ctx.fillText(hi.toPrecision(3), L - 4, T + 4); ctx.fillText(lo.toPrecision(3), L - 4, h - B);
    ctx.textAlign = "center"; ctx.fillText("time [s] 0 … " + t1.toFixed(0), w / 2, h - 5);
    ctx.strokeStyle = "#d5dbe2"; ctx.strokeRect(L, T, w - L - 8, h - T - B);
    if (limit !== null && limit !== undefined) {
      ctx.strokeStyle = "#b3261e"; ctx.setLineDash([6, 4]); ctx.beginPath();
      ctx.moveTo(L, py(limit)); ctx.lineTo(w - 8, py(limit)); ctx.stroke(); ctx.setLineDash([]);
      ctx.fillStyle = "#b3261e"; ctx.textAlign = "right";
      ctx.fillText("limit " + limit.toPrecision(3), w - 10, py(limit) - 3);
    }
    ctx.strokeStyle = "#1f4e9c"; ctx.lineWidth = 1.5; ctx.beginPath();
    var started = false;
    for (var i = 0; i < t.length; i++) {
      if (values[i] === null) { started = false; continue; }
      if (started) { ctx.lineTo(px(t[i]), py(values[i])); }
      else { ctx.moveTo(px(t[i]), py(values[i])); started = true; }
    }
    ctx.stroke();
  }
  function openRun(pathName, runNumber) {
    var path = data.paths.filter(function (p) { return p.name === pathName; })[0];
    var run = path && path.runs && path.runs[String(runNumber)];
    if (!run) {
      panel.style.display = "block";
      panel.querySelector("h3").textContent = pathName + " run " + runNumber +
        ": not among the runs this page holds";
      panel.querySelector(".charts").innerHTML = "";
      panel.querySelector(".params").textContent = "";
      return;
    }
    selected = {path: pathName, number: runNumber, run: run};
    panel.style.display = "block";
    panel.querySelector("h3").textContent = pathName + " · run " + runNumber + " · I_max " +
      percent(run.i_max) + (run.dominant ? " · dominant " + title(run.dominant) : "");
    panel.querySelector(".params").textContent = run.parameters.map(function (p) {
      return p[0] + " = " + p[1]; }).join(" · ");
    var charts = panel.querySelector(".charts");
    charts.innerHTML = "";
    var items = [{key: "risk", title: "per-sample risk", unit: "%"}].concat(data.series);
    items.forEach(function (s) {
      var values = s.key === "risk" ? (run.risk || null) && run.risk.map(function (v) {
        return v === null ? null : 100 * v; }) : run.series[s.key];
      if (!values) { return; }
      var el = document.createElement("canvas");
      el.setAttribute("data-series", s.key);
      charts.appendChild(el);
      var limit = s.key === "risk" ? 100 : data.limits[s.key];
      chart(el, run.t, values, limit === undefined ? null : limit, s.unit, s.title);
    });
    draw();
    panel.setAttribute("data-open", pathName + "/" + runNumber);
  }
  document.querySelectorAll("tr.run").forEach(function (row) {
    row.addEventListener("click", function () {
      openRun(row.getAttribute("data-path"), Number(row.getAttribute("data-run")));
      root.scrollIntoView({behavior: "smooth", block: "start"});
    });
  });
  document.querySelectorAll("#imap-paths input").forEach(function (box) {
    box.addEventListener("change", function () { on[box.value] = box.checked; draw(); });
  });
  window.addEventListener("resize", draw);
  function at(key) {  // client coordinates of a cell's centre (for scripted checks)
    var box = canvas.getBoundingClientRect(), col = key % g.nx, row = Math.floor(key / g.nx);
    return {x: box.left + sx(g.x0 + (col + 0.5) * g.cell),
            y: box.top + sy(g.y0 + (row + 0.5) * g.cell)};
  }
  function worst() {  // the worst-run marks drawn: label centre and end dot, client coordinates
    var box = canvas.getBoundingClientRect();
    return marks.map(function (m) {
      return {path: m.path, run: m.run, text: m.text, colour: m.colour,
              x: box.left + m.box.left + m.box.w / 2, y: box.top + m.box.top + m.box.h / 2,
              end: {x: box.left + m.x, y: box.top + m.y}, box: m.box};
    });
  }
  window.idefixReport = {openRun: openRun, cells: cellTable, draw: draw, at: at,
                         axes: function () { return axes; }, focus: focus, worst: worst};
  draw();
})();
"""
