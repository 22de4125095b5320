// aos viewer page: plain JavaScript, no build step, no external assets.
// Every request carries the session token from this page's URL. Sliders send render requests
// over the WebSocket while they move (preview: the full-size image from every k-th view, k chosen
// by the server to fit its frame budget) and a request for every view when the input rests
// (change event, or 50 ms without input). The server keeps only the
// newest request per page. window.aosStats records, per displayed frame, the time from the
// input event that caused it to its display (performance.now()): tools/bench_viewer.py reads it.
"use strict";

const token = new URLSearchParams(location.search).get("token") || "";
const $ = (id) => document.getElementById(id);
const canvas = $("image");
const context = canvas.getContext("2d");
const scratch = document.createElement("canvas");
const scratchContext = scratch.getContext("2d");

const stats = {
  sent: 0, shown: 0, errors: [], frames: [], inputTimes: {}, lastFrame: null, lastSentId: 0,
  lastFullId: 0, connected: false,
};
window.aosStats = stats;

let info = null;
let socket = null;
let nextId = 1;
let restTimer = null;
const SLIDERS = ["focal_height", "tilt_x_deg", "tilt_y_deg", "surface_offset", "aperture_radius",
  "view_first", "view_last", "pose_view", "orbit_deg", "tilt_deg", "pan_x", "pan_y", "pan_z",
  "fov_deg", "gain", "offset"];
const SELECTS = ["mode", "range", "colormap"];

function api(path, params) {
  const query = new URLSearchParams(params || {});
  query.set("token", token);
  return `${path}?${query.toString()}`;
}

function apertureMax() {
  return Number($("aperture_radius").max);
}

// The parameters of the current state (session.py's names).
function currentParams() {
  const params = {};
  for (const id of SLIDERS) params[id] = Number($(id).value);
  for (const id of SELECTS) params[id] = $(id).value;
  params.surface = $("surface").checked;
  if (params.aperture_radius >= apertureMax()) params.aperture_radius = "inf";
  if (params.view_last <= params.view_first) params.view_last = params.view_first + 1;
  params.width = info.defaults.width;
  params.height = info.defaults.height;
  return params;
}

function showValues() {
  for (const id of SLIDERS) {
    const out = $(id + "_out");
    if (!out) continue;
    let text = $(id).value;
    if (id === "aperture_radius" && Number(text) >= apertureMax()) text = "inf";
    if (id === "pose_view" && info) text = `${text} ${info.view_names[Number(text)] || ""}`;
    out.textContent = text;
  }
  $("surface_offset_row").style.display = $("surface").checked ? "" : "none";
}

function send(preview, inputTime) {
  if (!socket || socket.readyState !== WebSocket.OPEN) return;
  const id = nextId++;
  stats.inputTimes[id] = inputTime === undefined ? performance.now() : inputTime;
  stats.sent += 1;
  stats.lastSentId = id;
  if (!preview) stats.lastFullId = id;
  const params = currentParams();
  params.preview = preview;
  socket.send(JSON.stringify({ type: "render", id, params }));
  drawMinimap();
}

// One preview in flight at a time: inputs that come while it renders are folded into the next
// request, sent when its frame arrives (frames never queue up in the page, so the one shown is
// at most one render behind the input). A preview not answered in a second no longer holds.
let previewSentAt = null;
let heldInput = null;

function sendPreview(inputTime) {
  previewSentAt = performance.now();
  send(true, inputTime);
}

function releasePreview() {
  previewSentAt = null;
  if (heldInput !== null) {
    const inputTime = heldInput;
    heldInput = null;
    sendPreview(inputTime);
  }
}

function onInput(event) {
  const now = performance.now();
  showValues();
  if (previewSentAt !== null && now - previewSentAt < 1000) heldInput = now;
  else sendPreview(now);
  clearTimeout(restTimer);
  restTimer = setTimeout(() => { heldInput = null; send(false, now); }, 50);
}

function onChange() {
  const now = performance.now();
  showValues();
  clearTimeout(restTimer);
  heldInput = null;
  send(false, now);
}

// 2 -> "2nd", 11 -> "11th", 23 -> "23rd".
function ordinal(n) {
  const teen = n % 100 >= 11 && n % 100 <= 13;
  const suffix = teen ? "th" : ({ 1: "st", 2: "nd", 3: "rd" }[n % 10] || "th");
  return `${n}${suffix}`;
}

function handleFrame(buffer) {
  const view = new DataView(buffer);
  const length = view.getUint32(0, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 4, length)));
  const pixels = new Uint8ClampedArray(buffer, 4 + length, header.width * header.height * 4);
  if (header.id !== null && header.id < (stats.lastFrame ? stats.lastFrame.id : 0)) return;
  const image = new ImageData(pixels, header.width, header.height);
  if (canvas.width !== header.width || canvas.height !== header.height) {
    canvas.width = header.width;
    canvas.height = header.height;
  }
  scratch.width = header.width;
  scratch.height = header.height;
  scratchContext.putImageData(image, 0, 0);
  context.imageSmoothingEnabled = true;
  context.drawImage(scratch, 0, 0, canvas.width, canvas.height);
  const now = performance.now();
  const inputTime = stats.inputTimes[header.id];
  const record = {
    id: header.id, preview: !!header.preview, t: now, render_ms: header.render_ms,
    latency_ms: inputTime === undefined ? null : now - inputTime,
    width: header.width, height: header.height, views_used: header.views_used,
    view_stride: header.view_stride,
  };
  for (const key of Object.keys(stats.inputTimes)) {
    if (Number(key) <= header.id) delete stats.inputTimes[key];
  }
  stats.frames.push(record);
  if (stats.frames.length > 5000) stats.frames.shift();
  stats.lastFrame = record;
  stats.shown += 1;
  const recent = stats.frames.filter((f) => now - f.t < 1000).length;
  $("rate").textContent = `${header.width}x${header.height}` +
    `${header.preview ? ` preview (every ${header.view_stride === 1 ? "" : ordinal(header.view_stride) + " "}view)` : ""}` +
    ` render ${header.render_ms} ms, input to display ${record.latency_ms === null ? "-" :
      record.latency_ms.toFixed(0)} ms, ${recent} frames/s` +
    (header.views_used !== undefined ? `, ${header.views_used} of ${header.views_selected} views` : "") +
    `, ${header.uncovered_pixels || 0} pixels uncovered` +
    (header.display_range_c ? `, display ${header.display_range_c[0].toFixed(1)} .. ` +
      `${header.display_range_c[1].toFixed(1)} \u00b0C` : "");
  drawMarkers(header);
  if (header.allinfocus) finishJob("all-in-focus done");
}

// ---- detections: markers on the image, a list beside it ----

function drawMarkers(header) {
  stats.lastMarkers = header.markers || [];
  const sx = canvas.width / header.width, sy = canvas.height / header.height;
  context.lineWidth = 2;
  context.font = "bold 13px sans-serif";
  for (const [number, u, v] of stats.lastMarkers) {
    const x = u * sx, y = v * sy;
    context.strokeStyle = "#ff0";
    context.beginPath();
    context.arc(x, y, 9, 0, 2 * Math.PI);
    context.stroke();
    context.fillStyle = "#ff0";
    context.fillText(String(number), x + 11, y - 6);
  }
}

function centreOn(item) {
  if (!item.centre) return;
  $("pan_x").value = item.centre.pan_x;
  $("pan_y").value = item.centre.pan_y;
  if (!$("surface").checked) $("focal_height").value = item.centre.focal_height;
  onChange();
}

async function detect() {
  const params = currentParams();
  params.detector = $("detector").value;
  if (params.detector === "temperature") params.min_temperature_c = $("min_temperature_c").value;
  if (oneSidedApplies() && $("one_sided").checked) params.one_sided = true;
  $("detect_status").textContent = "detecting…";
  let response, answer;
  try {
    response = await fetch(api("/api/detect", params));
    answer = await response.json();
  } catch (error) {
    $("detect_status").textContent = `error: ${error}`;
    return null;
  }
  window.aosLastDetect = answer;
  const list = $("detections");
  list.textContent = "";
  if (!response.ok) {
    $("detect_status").textContent = `error: ${answer.error}`;
    return answer;
  }
  for (const item of answer.detections) {
    const entry = document.createElement("li");
    let text = `score ${item.peak_score.toFixed(1)}, ${item.area_px} px, ${item.views} views`;
    if (item.celsius !== null) text += `, ${item.celsius.toFixed(1)} \u00b0C`;
    if (item.lonlat) text += `, ${item.lonlat[1].toFixed(6)}, ${item.lonlat[0].toFixed(6)}`;
    entry.textContent = text;
    entry.addEventListener("click", () => centreOn(item));
    list.appendChild(entry);
  }
  $("detect_status").textContent = `${answer.detections.length} found (${answer.threshold_rule})`;
  onChange();  // the next frame carries the markers
  return answer;
}
window.aosDetect = detect;
$("detect").addEventListener("click", detect);
// One-sided scores (DetectOptions.one_sided): rx and anomaly imaging of one channel.
function oneSidedApplies() {
  return Boolean(info) && info.channels === 1 &&
    ["rx", "anomaly-imaging"].includes($("detector").value);
}
function showDetectorRows() {
  $("min_temperature_row").style.display = $("detector").value === "temperature" ? "" : "none";
  $("one_sided_row").style.display = oneSidedApplies() ? "" : "none";
}
$("detector").addEventListener("change", showDetectorRows);

function handleMessage(message) {
  if (message.type === "error") {
    releasePreview();
    stats.errors.push(message.message);
    $("status").textContent = `error: ${message.message}`;
    $("status").className = "error";
    if (jobRunning) finishJob("failed");
  } else if (message.type === "progress") {
    $("progress").max = message.total || 1;
    $("progress").value = message.done;
    $("status").textContent = `${message.stage}: ${message.done}/${message.total}`;
  } else if (message.type === "cancelled") {
    finishJob("cancelled");
  } else if (message.type === "download") {
    const link = document.createElement("a");
    link.href = `${message.url}?token=${encodeURIComponent(token)}`;
    link.download = "aos-focal-stack.zip";
    document.body.appendChild(link);
    link.click();
    link.remove();
    window.aosLastDownload = message;
    finishJob(`focal stack ready (${(message.bytes / 1048576).toFixed(1)} MiB zip)`);
  }
}

function connect() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  socket = new WebSocket(`${scheme}://${location.host}${api("/ws")}`);
  socket.binaryType = "arraybuffer";
  socket.onopen = () => {
    stats.connected = true;
    $("status").textContent = "connected";
    $("status").className = "";
    send(false);
  };
  socket.onmessage = (event) => {
    if (typeof event.data === "string") handleMessage(JSON.parse(event.data));
    else {
      try {
        handleFrame(event.data);
      } finally {
        releasePreview();
      }
    }
  };
  socket.onclose = (event) => {
    // A refusal (too many pages open: code 1013) says why in its reason.
    stats.connected = false;
    $("status").textContent = event.reason ? `disconnected: ${event.reason}` :
      "disconnected (the server stopped?)";
    $("status").className = "error";
  };
}

// ---- picking ----

canvas.addEventListener("click", async (event) => {
  const rect = canvas.getBoundingClientRect();
  const u = (event.clientX - rect.left) * canvas.width / rect.width;
  const v = (event.clientY - rect.top) * canvas.height / rect.height;
  await pickAt(u, v);
});

async function pickAt(u, v) {
  const params = currentParams();
  params.u = u;
  params.v = v;
  const response = await fetch(api("/api/pick", params));
  const answer = await response.json();
  window.aosLastPick = answer;
  if (!response.ok) {
    $("pick").textContent = `error: ${answer.error}`;
    return answer;
  }
  const f = (x) => x.toFixed(3);
  let text = `pixel (${u.toFixed(1)}, ${v.toFixed(1)}): `;
  if (answer.world) {
    text += `world (${answer.world.map(f).join(", ")})`;
    if (answer.lonlat) text += `  lon/lat (${answer.lonlat[0].toFixed(7)}, ${answer.lonlat[1].toFixed(7)})`;
    if (answer.depth !== null && answer.depth !== undefined) text += `  depth ${f(answer.depth)} m`;
  } else {
    text += "the ray misses the focal surface";
  }
  text += `  seen by ${answer.count} views`;
  if (answer.celsius) text += `  ${answer.celsius.map((c) => c.toFixed(2)).join(", ")} \u00b0C`;
  $("pick").textContent = text;
  return answer;
}
window.aosPickAt = pickAt;

// ---- mini-map: flight path, views in use, aperture ----

function drawMinimap() {
  if (!info) return;
  const map = $("minimap");
  const g = map.getContext("2d");
  g.clearRect(0, 0, map.width, map.height);
  const xs = info.centres.map((c) => c[0]);
  const ys = info.centres.map((c) => c[1]);
  const minX = Math.min(...xs), maxX = Math.max(...xs), minY = Math.min(...ys), maxY = Math.max(...ys);
  const span = Math.max(maxX - minX, maxY - minY, 1e-6) * 1.3;
  const cx = (minX + maxX) / 2, cy = (minY + maxY) / 2;
  const scale = map.width / span;
  const px = (x) => map.width / 2 + (x - cx) * scale;
  const py = (y) => map.height / 2 - (y - cy) * scale;  // north (+y) up
  const params = currentParams();
  const first = params.view_first, last = params.view_last;
  g.strokeStyle = "#555";
  g.beginPath();
  info.centres.forEach((c, i) => (i ? g.lineTo(px(c[0]), py(c[1])) : g.moveTo(px(c[0]), py(c[1]))));
  g.stroke();
  const pose = info.centres[params.pose_view];
  const radius = params.aperture_radius === "inf" ? Infinity : params.aperture_radius;
  info.centres.forEach((c, i) => {
    const used = i >= first && i < last;
    const inAperture = used && Math.hypot(c[0] - pose[0], c[1] - pose[1]) <= radius;
    g.fillStyle = inAperture ? "#6cf" : used ? "#357" : "#444";
    g.fillRect(px(c[0]) - 1.5, py(c[1]) - 1.5, 3, 3);
  });
  g.fillStyle = "#fc4";
  g.beginPath();
  g.arc(px(pose[0] + params.pan_x), py(pose[1] + params.pan_y), 4, 0, 2 * Math.PI);
  g.fill();
  if (isFinite(radius)) {
    g.strokeStyle = "#fc4";
    g.beginPath();
    g.arc(px(pose[0] + params.pan_x), py(pose[1] + params.pan_y), Math.max(radius * scale, 1), 0, 2 * Math.PI);
    g.stroke();
  }
}

// ---- buttons ----

async function fetchCommand() {
  const response = await fetch(api("/api/command", currentParams()));
  const answer = await response.json();
  if (!response.ok) throw new Error(answer.error);
  return answer;
}

async function copyText(text) {
  $("command").value = text;
  try { await navigator.clipboard.writeText(text); } catch (error) { $("command").select(); }
}

$("copy_cli").addEventListener("click", async () => copyText((await fetchCommand()).cli));
$("copy_python").addEventListener("click", async () => copyText((await fetchCommand()).python));
for (const button of document.querySelectorAll("[data-export]")) {
  button.addEventListener("click", () => {
    const params = currentParams();
    params.format = button.dataset.export;
    const link = document.createElement("a");
    link.href = api("/api/export", params);
    link.download = "";
    document.body.appendChild(link);
    link.click();
    link.remove();
  });
}

let jobRunning = false;
function finishJob(text) {
  jobRunning = false;
  $("cancel").disabled = true;
  $("allinfocus").disabled = false;
  $("stack").disabled = false;
  $("status").textContent = text;
}
function startJob(type) {
  // The stack spans the focus slider's range: heights (from under the cameras to beyond the
  // ground), or with focus on the surface its offsets (a terrain-following stack).
  const focus = $("surface").checked ? $("surface_offset") : $("focal_height");
  const lo = Number(focus.min), hi = Number(focus.max);
  jobRunning = true;
  $("cancel").disabled = false;
  $("allinfocus").disabled = true;
  $("stack").disabled = true;
  $("progress").value = 0;
  const id = nextId++;
  stats.inputTimes[id] = performance.now();
  const params = currentParams();
  socket.send(JSON.stringify({ type, id, params, first_height: lo,
    last_height: hi, slices: Number($("slices").value) }));
}
$("allinfocus").addEventListener("click", () => startJob("allinfocus"));
$("stack").addEventListener("click", () => startJob("stack"));
$("cancel").addEventListener("click", () => socket.send(JSON.stringify({ type: "cancel" })));
$("reset").addEventListener("click", () => { applyDefaults(); onChange(); });

// ---- start ----

function applyDefaults() {
  const d = info.defaults;
  const z = info.centres.reduce((s, c) => s + c[2], 0) / info.centres.length;
  // From just under the cameras (mean height z) to twice the starting focus's distance from
  // them, away from the cameras (the ground lies somewhere in there).
  const reach = 2 * Math.max(Math.abs(z - d.focal_height), 5);
  const away = d.focal_height >= z ? 1 : -1;
  const lo = Math.min(z + away * 0.5, z + away * reach);
  const hi = Math.max(z + away * 0.5, z + away * reach);
  Object.assign($("focal_height"), { min: lo.toFixed(2), max: hi.toFixed(2) });
  const xs = info.centres.map((c) => c[0]), ys = info.centres.map((c) => c[1]);
  // Whole metres, so that 0 is a step of the pan sliders (a range input snaps to min + k step).
  const extent = Math.ceil(Math.max(Math.max(...xs) - Math.min(...xs),
                                    Math.max(...ys) - Math.min(...ys), 1));
  Object.assign($("aperture_radius"), { max: (extent * 0.75).toFixed(1) });
  for (const id of ["pan_x", "pan_y"]) Object.assign($(id), { min: -extent, max: extent });
  $("view_first").max = info.view_count - 1;
  $("view_last").max = info.view_count;
  $("pose_view").max = info.view_count - 1;
  for (const id of SLIDERS) if (d[id] !== undefined) $(id).value = d[id];
  $("aperture_radius").value = d.aperture_radius === "inf" ? apertureMax() : d.aperture_radius;
  $("fov_deg").value = d.fov_deg || info.view_fov_deg[d.pose_view];
  for (const id of SELECTS) $(id).value = d[id];
  $("surface").checked = !!d.surface;
  $("surface_row").style.display = info.surface ? "" : "none";
  if (info.fixed_pose) $("pose_view").disabled = true;
  showValues();
}

async function start() {
  const response = await fetch(api("/api/info"));
  info = await response.json();
  $("source").textContent = `${info.source} (${info.view_count} views, ${info.dtype} x ${info.channels})`;
  applyDefaults();
  for (const id of SLIDERS) {
    $(id).addEventListener("input", onInput);
    $(id).addEventListener("change", onChange);
  }
  for (const id of SELECTS) $(id).addEventListener("change", onChange);
  if (!info.radiometric) $("detector").querySelector("option[value=temperature]").remove();
  showDetectorRows();
  $("surface").addEventListener("change", onChange);
  drawMinimap();
  connect();
}

start();
