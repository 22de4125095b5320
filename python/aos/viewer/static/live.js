// The live page (docs/live.md): asks /api/live for the next update (a long poll), then shows
// its image (/api/live/image), this update's detections as markers, the tracks found so far
// and the flight path. window.aosLive holds what tests read: the update shown, when it was
// shown, and how many updates were shown.
"use strict";
(function () {
  const token = new URLSearchParams(location.search).get("token") || "";
  const q = (name) => document.getElementById(name);
  const image = q("live-image"), markers = q("live-markers"), status = q("status");
  const svg = "http://www.w3.org/2000/svg";
  // history: [update, frame, shown at (ms since 1970)] of the last 2000 updates shown.
  window.aosLive = { update: 0, shown: 0, shownAt: 0, state: null, errors: 0, history: [] };
  let objectUrl = "";

  function element(name, attributes) {
    const e = document.createElementNS(svg, name);
    for (const [k, v] of Object.entries(attributes)) e.setAttribute(k, String(v));
    return e;
  }

  function drawMarkers(state) {
    markers.replaceChildren();
    markers.setAttribute("viewBox", `0 0 ${state.width} ${state.height}`);
    for (const d of state.detections) {
      const r = Math.max(6, Math.sqrt(d.area_px));
      markers.appendChild(element("circle", { cx: d.x, cy: d.y, r: r, class: "marker" }));
    }
  }

  function drawMap(state) {
    const map = q("minimap");
    map.replaceChildren();
    const points = state.path.concat(state.window_path);
    for (const t of state.tracks) if (t.local[0] !== null) points.push([t.local[0], t.local[1]]);
    if (points.length === 0) return;
    let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
    for (const [x, y] of points) {
      x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y);
    }
    const span = Math.max(x1 - x0, y1 - y0, 1), s = 220 / span;
    const at = ([x, y]) => [10 + (x - x0) * s, 230 - (y - y0) * s];  // north up
    const line = (list, attributes) => {
      if (list.length < 2) return;
      map.appendChild(element("polyline", Object.assign(
        { points: list.map((p) => at(p).join(",")).join(" "), fill: "none" }, attributes)));
    };
    line(state.path, { stroke: "#888", "stroke-width": 1, id: "live-path" });
    line(state.window_path, { stroke: "#4af", "stroke-width": 3 });
    state.tracks.forEach((t, i) => {
      if (t.local[0] === null) return;
      const [cx, cy] = at([t.local[0], t.local[1]]);
      map.appendChild(element("circle", { cx, cy, r: i === 0 ? 5 : 3, fill: "#ff3b30" }));
    });
  }

  function drawTracks(state) {
    const list = q("tracks");
    list.replaceChildren();
    for (const t of state.tracks.slice(0, 50)) {
      const li = document.createElement("li");
      const where = t.lon_lat ? `${t.lon_lat[1].toFixed(6)}, ${t.lon_lat[0].toFixed(6)}`
        : t.world[0] === null ? "not located" : t.world.map((v) => v.toFixed(1)).join(" ");
      const peak = t.peak_score === null ? "?" : t.peak_score.toFixed(1);
      li.textContent = `${where}  peak ${peak}  ×${t.sightings} ` +
        `(${t.first_frame} .. ${t.last_frame})`;
      list.appendChild(li);
    }
  }

  async function show(state) {
    const response = await fetch(`api/live/image?token=${encodeURIComponent(token)}&update=${state.update}`);
    if (response.ok) {
      const blob = await response.blob();
      const url = URL.createObjectURL(blob);
      await new Promise((resolve) => { image.onload = resolve; image.onerror = resolve; image.src = url; });
      if (objectUrl) URL.revokeObjectURL(objectUrl);
      objectUrl = url;
    }
    drawMarkers(state);
    drawMap(state);
    drawTracks(state);
    q("frame").textContent = state.frame;
    q("window").textContent = `window ${state.window.length}/${state.window_frames} frames`;
    status.textContent = `update ${state.update}: ${state.detections.length} detections, ` +
      `${state.tracks.length} places found`;
    const live = window.aosLive;
    live.update = state.update; live.shown += 1; live.shownAt = Date.now(); live.state = state;
    live.history.push([state.update, state.frame, live.shownAt]);
    if (live.history.length > 2000) live.history.shift();
    if (state.frame_seen_unix) {
      q("rate").textContent = `frame to page ${(Date.now() - 1000 * state.frame_seen_unix).toFixed(0)} ms`;
    }
  }

  async function loop() {
    for (;;) {
      try {
        const response = await fetch(`api/live?token=${encodeURIComponent(token)}&after=${window.aosLive.update}`);
        if (response.status === 200) {
          const state = await response.json();
          if (state.update > window.aosLive.update) await show(state);
        } else if (response.status !== 204) {
          status.textContent = `error ${response.status}`;
          window.aosLive.errors += 1;
          await new Promise((r) => setTimeout(r, 1000));
        }
      } catch (error) {
        status.textContent = "connection lost; retrying";
        window.aosLive.errors += 1;
        await new Promise((r) => setTimeout(r, 1000));
      }
    }
  }
  loop();
})();
