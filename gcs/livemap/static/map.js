// gcs fly --map: the page. Leaflet over the plan's own base layer (no tiles: offline),
// plan.json once, state.json every second. window.gcsMap exposes what the page shows
// (tests read it; nothing depends on it).
"use strict";

(function () {
  const map = L.map("map", { zoomSnap: 0.25, preferCanvas: false });
  L.control.scale({ imperial: false, maxWidth: 160 }).addTo(map);
  const live = { vehicles: {}, replans: {}, plan: null, updates: 0, lastState: null };
  const layers = { tracks: L.layerGroup().addTo(map), snaps: L.layerGroup().addTo(map),
                   replans: L.layerGroup().addTo(map), marks: L.layerGroup().addTo(map) };

  function div(cls, html, size, anchor) {
    return L.divIcon({ className: cls, html: html || "", iconSize: size,
                       iconAnchor: anchor || [size[0] / 2, size[1] / 2] });
  }

  function drawPlan(p) {
    live.plan = p;
    document.getElementById("title").textContent = "gcs fly: " + p.title;
    const b = p.base.bounds;
    L.imageOverlay(p.base.url, b, { interactive: false, className: "base-layer" }).addTo(map);
    map.fitBounds(b);
    map.setMaxBounds(L.latLngBounds(b).pad(0.5));
    document.getElementById("ceiling-scale").src = p.base.scale;
    document.getElementById("ceiling-max").textContent = Math.round(p.base.ceiling_agl_m[1]);
    for (const poly of p.area) {
      L.polygon(poly, { color: "#000", weight: 2, dashArray: "6 4", fill: false }).addTo(map);
      document.getElementById("area-legend").hidden = false;
    }
    for (const o of p.outposts) {
      if (o.range_m) {
        L.circle([o.lat, o.lon], { radius: o.range_m, color: p.colours.outpost, weight: 1.5,
                                   dashArray: "3 4", fill: true, fillOpacity: 0.04 }).addTo(map)
          .bindTooltip(o.name + ": " + (o.range_m / 1000) + " km range", { sticky: true });
      }
      const range = o.range_m ? (o.range_m / 1000) + " km range" : "range unlimited";
      L.marker([o.lat, o.lon], { icon: div("outpost-icon", "&#x25B2;", [20, 20]) }).addTo(map)
        .bindTooltip(o.name + " (" + range + ")", { permanent: true, direction: "right",
                                                   offset: [8, 0], className: "outpost-label" });
    }
    for (const r of p.routes) {
      L.polyline(r.points, { color: r.colour, weight: 2, opacity: 0.35 }).addTo(map);
      for (const s of r.snapshots) {
        L.circleMarker(s, { radius: 2, color: r.colour, weight: 1, opacity: 0.45,
                            fillOpacity: 0.3 }).addTo(map);
      }
    }
    for (const r of p.routes) {
      if (r.launch) {
        L.marker([r.launch[0], r.launch[1]], { icon: div("base-icon", "", [11, 11]),
                                               zIndexOffset: 500 })
          .addTo(map).bindTooltip("base of UAV " + r.vehicle + ": " +
                                  r.launch[2].toFixed(1) + " m AMSL (ground)");
      }
    }
  }

  function vehicle(v) {
    let e = live.vehicles[v.sysid];
    if (!e) {
      e = live.vehicles[v.sysid] = {
        track: L.polyline([], { color: v.colour, weight: 3, opacity: 0.95 }).addTo(layers.tracks),
        marker: null, snaps: L.layerGroup().addTo(layers.snaps), nSnaps: 0, lost: false,
        moves: 0, last: null };
    }
    e.track.setLatLngs(v.track);
    for (let i = e.nSnaps; i < v.snapshots.length; i++) {
      L.circleMarker(v.snapshots[i], { radius: 4, color: "#000", weight: 1, fillColor: v.colour,
                                       fillOpacity: v.state === "lost" ? 0.4 : 1 }).addTo(e.snaps);
    }
    e.nSnaps = v.snapshots.length;
    if (v.position) {
      const lost = v.state === "lost";
      if (!e.marker || lost !== e.lost) {
        if (e.marker) layers.marks.removeLayer(e.marker);
        const icon = lost
          ? div("vehicle lost-marker vehicle-" + v.sysid, "&#x2716;", [22, 22])
          : div("vehicle vehicle-" + v.sysid, String(v.sysid), [16, 16]);
        e.marker = L.marker(v.position, { icon: icon, zIndexOffset: 1000 }).addTo(layers.marks);
        if (!lost) e.marker.getElement().style.background = v.colour;
        else e.marker.getElement().style.color = v.colour;
        e.lost = lost;
      }
      if (!e.last || e.last[0] !== v.position[0] || e.last[1] !== v.position[1]) e.moves++;
      e.marker.setLatLng(v.position);
      e.marker.bindTooltip("sysid " + v.sysid + " (UAV " + v.vehicle + "): " + v.state +
                           (v.alt_amsl !== null ? ", " + v.alt_amsl.toFixed(0) + " m AMSL" : ""));
      e.last = v.position;
    }
  }

  function replans(list) {
    for (const r of list) {
      if (live.replans[r.n]) continue;
      live.replans[r.n] = true;
      for (const [sysid, points] of Object.entries(r.routes)) {
        if (!points.length) continue;
        const colour = (live.lastState.vehicles.find((v) => String(v.sysid) === sysid) || {})
          .colour || "#000";
        L.polyline(points, { color: "#fff", weight: 5, opacity: 0.7 }).addTo(layers.replans);
        L.polyline(points, { color: colour, weight: 2.5, dashArray: "8 5" })
          .addTo(layers.replans).bindTooltip("re-plan " + r.n + " for sysid " + sysid);
      }
    }
  }

  function cell(text) { const td = document.createElement("td"); td.textContent = text; return td; }

  // down between two sorties: the operator's word that its battery is swapped
  function swapCell(v) {
    const td = document.createElement("td");
    if (!v.swap) return td;
    const button = document.createElement("button");
    button.textContent = "battery swapped";
    button.className = "swap";
    button.onclick = () => {
      button.disabled = true;
      fetch("swap", { method: "POST", headers: { "Content-Type": "application/json" },
                      body: JSON.stringify({ sysid: v.sysid }) })
        .then((r) => { if (!r.ok) { button.disabled = false; alert("not taken: " + r.statusText); } });
    };
    td.append(button);
    return td;
  }

  function table(state) {
    const body = document.querySelector("#vehicles tbody");
    body.replaceChildren();
    for (const v of state.vehicles) {
      const tr = document.createElement("tr");
      tr.className = v.state;
      const id = cell(String(v.sysid));
      const sw = document.createElement("span");
      sw.className = "swatch";
      sw.style.background = v.colour;
      id.prepend(sw);
      tr.append(id, cell(String(v.vehicle)), cell(v.mode || "?"), cell(v.state),
                cell((v.item === null ? "-" : v.item) + "/" + v.items),
                cell(v.snapshots.length + " (" + v.snapshots_done + "/" + v.snapshots_planned + ")"),
                cell(v.alt_amsl === null ? "-" : v.alt_amsl.toFixed(0) + " m"),
                cell(v.alt_above_home === null ? "-" : v.alt_above_home.toFixed(0) + " m"),
                cell(v.heartbeat_s === null ? "-" : v.heartbeat_s.toFixed(1) + " s"),
                swapCell(v));
      body.append(tr);
    }
    const events = document.getElementById("events");
    events.replaceChildren(...state.events.slice().reverse().map((t) => {
      const li = document.createElement("li"); li.textContent = t; return li; }));
    document.getElementById("clock").textContent =
      "flight time " + state.t_s.toFixed(0) + " s (wall clock); " +
      state.vehicles.filter((v) => v.state === "lost").length + " lost, " +
      state.replans.length + " re-plan(s)";
  }

  function update(state) {
    live.lastState = state;
    for (const v of state.vehicles) vehicle(v);
    replans(state.replans);
    table(state);
    live.updates++;
  }

  function poll() {
    fetch("state.json", { cache: "no-store" })
      .then((r) => r.json()).then(update)
      .catch(() => { document.getElementById("clock").textContent = "gcs fly has stopped"; })
      .finally(() => setTimeout(poll, 1000));
  }

  fetch("plan.json").then((r) => r.json()).then((p) => { drawPlan(p); poll(); });

  window.gcsMap = {
    map: map,
    updates: () => live.updates,
    vehicles: () => Object.fromEntries(Object.entries(live.vehicles).map(([s, e]) =>
      [s, { latlng: e.marker ? [e.marker.getLatLng().lat, e.marker.getLatLng().lng] : null,
            moves: e.moves, snapshots: e.nSnaps, lost: e.lost,
            track: e.track.getLatLngs().length }])),
    replans: () => Object.keys(live.replans).length,
  };
})();
