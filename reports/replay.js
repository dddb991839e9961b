/* The replay of a recorded run (reports/replay_data.py builds its data; replay_page.py the
 * HTML around it). One clock drives one or two lanes (two: `pnp-twin compare`). Each lane
 * draws the line seen from above on a canvas: the belt moving, every robot's workspace, base,
 * reach and bin (or the outfeed and its containers), the parts coloured by kind (fill) and
 * fate (ring), each tool on its recorded path, breakdowns and box changes, a clock and the
 * running gripping rate. What a lane drew last is kept in `lane.drawn` ({t, parts: {id: [x,
 * y]}, tools: [[x, y], ...]}) so a test can read it back; window.pnpReplays lists the
 * replays of the page. No network, no libraries. */
(function () {
  "use strict";
  if (window.PnpReplay) { window.PnpReplay.mountAll(); return; }
  var LOST = "#e63946", DESIGN = "#a3acb9", TODO = "#1d2733", HILITE = "#ffb703";
  var STATE_NAMES = ["DOWN", "box change", "holding", "wait", "interrupted", "box change"];

  function moveTime(d, v, a) {
    if (a <= 0) return d / v;
    var ramp = v * v / a;
    return d >= ramp ? d / v + v / a : 2 * Math.sqrt(d / a);
  }
  function along(x0, y0, x1, y1, e, v, a) { // twin.geometry.position_along
    var d = Math.hypot(x1 - x0, y1 - y0);
    if (d <= 0) return [x0, y0];
    var total = moveTime(d, v, a);
    if (e >= total) return [x1, y1];
    var done;
    if (a <= 0) done = v * e;
    else {
      var tAcc = Math.min(v / a, total / 2), top = a * tAcc;
      if (e <= tAcc) done = 0.5 * a * e * e;
      else if (e <= total - tAcc) done = 0.5 * top * tAcc + top * (e - tAcc);
      else { var left = total - e; done = d - 0.5 * a * left * left; }
    }
    var f = done / d;
    return [x0 + f * (x1 - x0), y0 + f * (y1 - y0)];
  }
  function legAt(g, t, v, a) {
    if (t >= g[1]) return [g[4], g[5]];
    if (t <= g[0]) return [g[2], g[3]];
    if (g[6] === 1) {
      var f = (t - g[0]) / (g[1] - g[0]);
      return [g[2] + f * (g[4] - g[2]), g[3] + f * (g[5] - g[3])];
    }
    return along(g[2], g[3], g[4], g[5], t - g[0], v, a);
  }
  function lastStarted(legs, t) { // index of the last leg with t0 <= t, -1: none
    var lo = 0, hi = legs.length - 1, best = -1;
    while (lo <= hi) {
      var mid = (lo + hi) >> 1;
      if (legs[mid][0] <= t) { best = mid; lo = mid + 1; } else hi = mid - 1;
    }
    return best;
  }
  function toolsAt(d, t) {
    return d.robots.map(function (r, i) {
      var legs = d.legs[i], k = lastStarted(legs, t);
      if (k >= 0) return legAt(legs[k], t, r.speed, r.acc);
      if (legs.length) return [legs[0][2], legs[0][3]];
      return [r.base[0], r.base[1]];
    });
  }
  function partsAt(d, t, tools) { // replay_data.parts_at
    var p = d.parts, v = d.belt.speed, out = {};
    for (var i = 0; i < p.id.length; i++) {
      var fed = p.fed[i], picked = p.picked[i], placed = p.placed[i];
      if (t < fed) continue;
      if (picked === null || t < picked) {
        if (p.fate[i] !== 0 && t >= p.left[i]) continue;
        out[p.id[i]] = [v * (t - fed), p.y[i], i, false];
      } else if (placed === null || t < placed) {
        var tl = tools[p.robot[i]];
        out[p.id[i]] = [tl[0], tl[1], i, true];
      }
    }
    return out;
  }
  function running(d, t) {
    var p = d.parts, picked = d.before.picked, lost = d.before.lost;
    for (var i = 0; i < p.id.length; i++) {
      if (!p.counted[i]) continue;
      if (p.fate[i] === 0) { if (p.picked[i] !== null && p.picked[i] < t && p.picked[i] >= d.t0) picked++; }
      else if (p.fate[i] === 1 && p.left[i] < t && p.left[i] >= d.t0) lost++;
    }
    return { picked: picked, lost: lost, g: picked + lost ? 100 * picked / (picked + lost) : NaN };
  }
  function statesAt(d, t) { // robot -> [state codes]
    var out = d.robots.map(function () { return []; });
    d.states.forEach(function (s) { if (s[2] <= t && t < s[3]) out[s[0]].push(s[1]); });
    return out;
  }
  function bounds(d) {
    var xs = [-0.1, d.belt.length + 0.1], ys = [-0.06, d.belt.width + 0.06];
    d.robots.forEach(function (r) {
      xs.push(r.bin[0]); ys.push(r.bin[1] - 0.1, r.bin[1] + 0.1, r.base[1], r.mount[1]);
    });
    if (d.outfeed) {
      var o = d.outfeed;
      xs.push(o.lo, o.hi); ys.push(o.y - o.width / 2 - 0.06, o.y + o.width / 2 + 0.06);
    }
    return [Math.min.apply(null, xs), Math.max.apply(null, xs),
            Math.min.apply(null, ys) - 0.04, Math.max.apply(null, ys) + 0.1];
  }
  function rgba(hex, a) {
    var h = hex.replace("#", "");
    return "rgba(" + parseInt(h.substr(0, 2), 16) + "," + parseInt(h.substr(2, 2), 16) + "," +
      parseInt(h.substr(4, 2), 16) + "," + a + ")";
  }

  function Lane(root, data, other) {
    this.d = data; this.canvas = root.querySelector("canvas"); this.head = root.querySelector(".rp-g");
    this.b = bounds(data); this.drawn = null; this.diff = {};
    this.lostParts = [];
    var p = data.parts;
    for (var i = 0; i < p.id.length; i++) if (p.fate[i] === 1) this.lostParts.push([p.left[i], p.id[i]]);
    this.lostParts.sort(function (a, b) { return a[0] - b[0]; });
  }
  Lane.prototype.size = function () {
    var w = this.canvas.clientWidth || 900, b = this.b;
    this.scale = w / (b[1] - b[0]);
    var h = Math.max(120, Math.min(560, Math.round((b[3] - b[2]) * this.scale)));
    if ((b[3] - b[2]) * this.scale > 560) this.scale = 560 / (b[3] - b[2]);
    var dpr = window.devicePixelRatio || 1;
    this.canvas.style.height = h + "px";
    this.canvas.width = Math.round(w * dpr); this.canvas.height = Math.round(h * dpr);
    this.dpr = dpr; this.w = w; this.h = h;
  };
  Lane.prototype.X = function (x) { return (x - this.b[0]) * this.scale; };
  Lane.prototype.Y = function (y) { return (this.b[3] - y) * this.scale; };
  Lane.prototype.draw = function (t, hilite) {
    var d = this.d, c = this.canvas.getContext("2d"), s = this.scale, self = this;
    var X = function (x) { return self.X(x); }, Y = function (y) { return self.Y(y); };
    c.setTransform(this.dpr, 0, 0, this.dpr, 0, 0);
    c.clearRect(0, 0, this.w, this.h);
    c.fillStyle = "#f7f9fb"; c.fillRect(0, 0, this.w, this.h);
    var L = d.belt.length, W = d.belt.width, v = d.belt.speed;
    // the belt, its slats moving at belt speed
    c.fillStyle = "#4a4f57"; c.fillRect(X(0), Y(W), L * s, W * s);
    c.strokeStyle = "rgba(255,255,255,0.10)"; c.lineWidth = 1;
    var pitch = 0.1, off = (v * t) % pitch;
    for (var x = off; x < L; x += pitch) { c.beginPath(); c.moveTo(X(x), Y(0)); c.lineTo(X(x), Y(W)); c.stroke(); }
    c.fillStyle = "#9aa5b1"; c.font = "11px sans-serif"; c.textAlign = "left";
    c.fillText("feeder \u2192", X(0) + 2, Y(0) + 13);
    c.textAlign = "right"; c.fillText("return conveyor \u2192", X(L) - 2, Y(0) + 13);
    var states = statesAt(d, t);
    d.robots.forEach(function (r, i) {
      c.fillStyle = rgba(r.colour, 0.16); c.fillRect(X(r.workspace[0]), Y(W), (r.workspace[1] - r.workspace[0]) * s, W * s);
      c.setLineDash([4, 3]); c.strokeStyle = rgba(r.colour, 0.9); c.lineWidth = 1.2;
      c.strokeRect(X(r.workspace[0]), Y(W), (r.workspace[1] - r.workspace[0]) * s, W * s);
      if (r.reach > 0) { c.beginPath(); c.arc(X(r.mount[0]), Y(r.mount[1]), r.reach * s, 0, 2 * Math.PI); c.stroke(); }
      c.setLineDash([]);
      if (!d.outfeed) {
        var changing = states[i].indexOf(5) >= 0, hb = 0.045 * s;
        c.fillStyle = changing ? "#ffb703" : rgba(r.colour, 0.25);
        c.fillRect(X(r.bin[0]) - hb, Y(r.bin[1]) - hb, 2 * hb, 2 * hb);
        c.strokeStyle = r.colour; c.lineWidth = 1.5; c.strokeRect(X(r.bin[0]) - hb, Y(r.bin[1]) - hb, 2 * hb, 2 * hb);
        c.fillStyle = "#1d2733"; c.textAlign = "center"; c.font = "11px sans-serif";
        var below = r.bin[1] < 0 ? hb + 12 : -hb - 4;
        c.fillText(changing ? "box change" : r.name + " bin", X(r.bin[0]), Y(r.bin[1]) + below);
      }
    });
    if (d.outfeed) this.drawOutfeed(c, t);
    var tools = toolsAt(d, t), parts = partsAt(d, t, tools), p = d.parts, drawn = {};
    // claims: a line from the tool to the part it is going for
    for (var id in parts) {
      var q = parts[id], i = q[2];
      if (!q[3] && p.fate[i] === 0 && p.decided[i] !== null && p.decided[i] <= t) {
        var tl = tools[p.robot[i]];
        c.strokeStyle = rgba(d.robots[p.robot[i]].colour, 0.8); c.lineWidth = 1.2;
        c.beginPath(); c.moveTo(X(tl[0]), Y(tl[1])); c.lineTo(X(q[0]), Y(q[1])); c.stroke();
      }
    }
    var rad = Math.max(3, 0.014 * s);
    for (var id2 in parts) {
      var q2 = parts[id2], k = q2[2], fate = p.fate[k];
      drawn[id2] = [q2[0], q2[1]];
      if (self.diff[id2]) { c.fillStyle = rgba(HILITE, 0.55); c.beginPath(); c.arc(X(q2[0]), Y(q2[1]), rad * 2.2, 0, 2 * Math.PI); c.fill(); }
      c.fillStyle = d.kindColours[p.kind[k]] || "#fff";
      c.beginPath(); c.arc(X(q2[0]), Y(q2[1]), rad, 0, 2 * Math.PI); c.fill();
      var ring = fate === 1 ? LOST : fate === 2 ? DESIGN : (p.decided[k] !== null && p.decided[k] <= t ? d.robots[p.robot[k]].colour : TODO);
      c.strokeStyle = ring; c.lineWidth = fate === 1 ? 2.2 : 1.6; c.stroke();
      if (+id2 === hilite) {
        c.strokeStyle = LOST; c.lineWidth = 2; c.beginPath();
        c.arc(X(q2[0]), Y(q2[1]), rad * 3 + 2 * Math.sin(t * 8), 0, 2 * Math.PI); c.stroke();
      }
    }
    // the robots: arm from base to tool, the tool, their state
    d.robots.forEach(function (r, i) {
      var tl = tools[i], down = states[i].indexOf(0) >= 0, ts = Math.max(4, 0.02 * s);
      c.strokeStyle = rgba(r.colour, 0.45); c.lineWidth = 2;
      c.beginPath(); c.moveTo(X(r.mount[0]), Y(r.mount[1])); c.lineTo(X(tl[0]), Y(tl[1])); c.stroke();
      c.fillStyle = r.colour; c.beginPath(); c.arc(X(r.mount[0]), Y(r.mount[1]), 5, 0, 2 * Math.PI); c.fill();
      c.fillStyle = down ? "#6c757d" : r.colour; c.strokeStyle = "#fff"; c.lineWidth = 1.5;
      c.fillRect(X(tl[0]) - ts / 2, Y(tl[1]) - ts / 2, ts, ts); c.strokeRect(X(tl[0]) - ts / 2, Y(tl[1]) - ts / 2, ts, ts);
      var label = states[i].filter(function (k) { return k !== 5; }).map(function (k) { return STATE_NAMES[k]; });
      c.font = "bold 11px sans-serif"; c.textAlign = "left";
      c.fillStyle = down ? LOST : "#1d2733";
      c.fillText(r.name + (label.length ? " " + label.join(", ") : ""), X(r.mount[0]) + 8, Y(r.mount[1]) - 6);
      if (down) {
        c.strokeStyle = LOST; c.lineWidth = 2.5; c.beginPath();
        c.moveTo(X(tl[0]) - ts, Y(tl[1]) - ts); c.lineTo(X(tl[0]) + ts, Y(tl[1]) + ts);
        c.moveTo(X(tl[0]) + ts, Y(tl[1]) - ts); c.lineTo(X(tl[0]) - ts, Y(tl[1]) + ts); c.stroke();
      }
    });
    var g = running(d, t);
    c.fillStyle = "rgba(255,255,255,0.85)"; c.fillRect(4, 4, 330, 20);
    c.fillStyle = "#1d2733"; c.font = "bold 13px sans-serif"; c.textAlign = "left";
    var gt = isNaN(g.g) ? "–" : g.g.toFixed(1) + " %";
    c.fillText("t = " + t.toFixed(1) + " s   G = " + gt + "  (" + g.picked + " picked, " + g.lost + " lost)", 8, 19);
    if (this.head) this.head.textContent = "G so far " + gt;
    this.drawn = { t: t, parts: drawn, tools: tools };
    this.g = g;
  };
  Lane.prototype.drawOutfeed = function (c, t) {
    var o = this.d.outfeed, s = this.scale, self = this;
    var X = function (x) { return self.X(x); }, Y = function (y) { return self.Y(y); };
    var half = o.width / 2 + 0.02;
    c.fillStyle = "#c9ced6"; c.fillRect(X(o.lo), Y(o.y + half), (o.hi - o.lo) * s, 2 * half * s);
    c.fillStyle = "#5f6b7a"; c.font = "11px sans-serif"; c.textAlign = o.u > 0 ? "right" : "left";
    c.fillText(o.u > 0 ? "outfeed \u2192" : "\u2190 outfeed", o.u > 0 ? X(o.hi) - 3 : X(o.lo) + 3, Y(o.y - half) - 3);
    var filled = {};
    o.fills.forEach(function (f) { if (f[2] <= t) filled[f[0] + ":" + f[1]] = true; });
    c.save(); c.beginPath(); c.rect(X(o.lo), Y(o.y + half), (o.hi - o.lo) * s, 2 * half * s); c.clip();
    o.times.forEach(function (at, j) {
      if (at > t) return;
      var cn = o.first + j, cx = o.xIn + o.u * (t - at);
      if (cx < o.lo - o.length || cx > o.hi + o.length) return;
      c.fillStyle = "#fff"; c.strokeStyle = "#8c6d31"; c.lineWidth = 1.3;
      c.fillRect(X(cx - o.length / 2), Y(o.y + o.width / 2), o.length * s, o.width * s);
      c.strokeRect(X(cx - o.length / 2), Y(o.y + o.width / 2), o.length * s, o.width * s);
      for (var k = 0; k < o.dx.length; k++) {
        var sx = cx + o.dx[k], sy = o.y + o.dy[k], r = Math.max(3, 0.018 * s);
        c.beginPath(); c.arc(X(sx), Y(sy), r, 0, 2 * Math.PI);
        c.fillStyle = filled[cn + ":" + k] ? "#2a9d8f" : "#eef1f5"; c.fill();
        c.strokeStyle = "#8c6d31"; c.lineWidth = 1; c.stroke();
      }
    });
    c.restore();
  };

  function Replay(el) {
    var data = JSON.parse(el.querySelector("script.rp-data").textContent);
    var lanes = el.querySelectorAll(".rp-lane"), self = this;
    this.el = el;
    this.lanes = data.map(function (d, i) { return new Lane(lanes[i], d); });
    var d0 = data[0];
    this.t0 = d0.t0; this.t1 = d0.t1; this.t = d0.t0; this.playing = false; this.hilite = -1;
    if (data.length === 2) this.markDiff(data);
    this.scrub = el.querySelector(".rp-scrub"); this.clock = el.querySelector(".rp-clock");
    this.button = el.querySelector(".rp-play"); this.speed = el.querySelector(".rp-speed");
    this.diffBox = el.querySelector(".rp-diff");
    this.scrub.min = this.t0; this.scrub.max = this.t1; this.scrub.step = 0.05; this.scrub.value = this.t0;
    this.button.addEventListener("click", function () { self.toggle(); });
    this.scrub.addEventListener("input", function () { self.seek(parseFloat(self.scrub.value)); });
    el.querySelector(".rp-lost").addEventListener("click", function () { self.nextLost(); });
    window.addEventListener("resize", function () { self.resize(); });
    this.resize();
  }
  Replay.prototype.markDiff = function (data) {
    // parts one policy grips and the other loses (the same seed feeds the same parts)
    var fates = data.map(function (d) {
      var m = {}; d.parts.id.forEach(function (id, i) { m[id] = d.parts.fate[i]; }); return m;
    });
    for (var id in fates[0]) {
      if (fates[1][id] === undefined) continue;
      if (fates[0][id] === 0 && fates[1][id] === 1) { this.lanes[0].diff[id] = 1; this.lanes[1].diff[id] = 1; }
      if (fates[0][id] === 1 && fates[1][id] === 0) { this.lanes[0].diff[id] = 1; this.lanes[1].diff[id] = 1; }
    }
  };
  Replay.prototype.resize = function () { this.lanes.forEach(function (l) { l.size(); }); this.draw(); };
  Replay.prototype.draw = function () {
    var t = this.t, h = this.hilite;
    this.lanes.forEach(function (l) { l.draw(t, h); });
    this.clock.textContent = "t = " + t.toFixed(1) + " s";
    this.scrub.value = t;
    if (this.diffBox && this.lanes.length === 2) {
      var a = this.lanes[0].g.g, b = this.lanes[1].g.g;
      var diff = b - a, names = this.lanes[1].d.title + " \u2212 " + this.lanes[0].d.title;
      this.diffBox.textContent = isNaN(diff) ? "" : "G so far, " + names + ": " + (diff >= 0 ? "+" : "") + diff.toFixed(1) + " points";
    }
  };
  Replay.prototype.seek = function (t) { this.t = Math.min(Math.max(t, this.t0), this.t1); this.draw(); };
  Replay.prototype.toggle = function () {
    if (this.playing) { this.playing = false; this.button.textContent = "\u25B6 Play"; return; }
    if (this.t >= this.t1) this.t = this.t0;
    this.playing = true; this.button.textContent = "\u275A\u275A Pause";
    var self = this, last = null;
    function tick(now) {
      if (!self.playing) return;
      if (last !== null) {
        var dt = Math.min((now - last) / 1000, 0.25) * parseFloat(self.speed.value);
        self.t = Math.min(self.t + dt, self.t1);
      }
      last = now; self.draw();
      if (self.t >= self.t1) { self.toggle(); return; }
      window.requestAnimationFrame(tick);
    }
    window.requestAnimationFrame(tick);
  };
  Replay.prototype.nextLost = function () {
    var t = this.t, best = null;
    this.lanes.forEach(function (l) {
      for (var i = 0; i < l.lostParts.length; i++) {
        var e = l.lostParts[i];
        if (e[0] > t + 3.05 && e[0] <= l.d.t1 && (best === null || e[0] < best[0])) { best = e; break; }
      }
    });
    if (best === null) { this.clock.textContent = "t = " + t.toFixed(1) + " s (no more lost parts)"; return; }
    this.hilite = best[1];
    this.seek(best[0] - 3);
  };

  window.PnpReplay = {
    mountAll: function () {
      window.pnpReplays = window.pnpReplays || [];
      document.querySelectorAll("[data-replay]").forEach(function (el) {
        if (el.replay) return;
        el.replay = new Replay(el);
        window.pnpReplays.push(el.replay);
      });
    },
    toolsAt: toolsAt, partsAt: partsAt
  };
  window.PnpReplay.mountAll();
})();
