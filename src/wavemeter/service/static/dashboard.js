// The live dashboard of `wavemeter serve`: one card per channel, fed by the /ws WebSocket.
"use strict";
(() => {
  const TRACE_POINTS = 3000;
  const query = new URLSearchParams(location.search);
  const token = query.get("token");
  const cards = new Map();
  const connection = document.getElementById("connection");
  if (token) {
    document.getElementById("metrics").href = "metrics?token=" + encodeURIComponent(token);
  }

  function text(element, value) {
    if (element.textContent !== value) element.textContent = value;
  }

  function plot(title, xLabel, yLabel, logScale, width) {
    const options = {
      title, width, height: 220,
      scales: logScale ? {x: {time: false, distr: 3}, y: {distr: 3}} : {x: {time: false}},
      axes: [{label: xLabel}, {label: yLabel, size: 70}],
      series: [{}, {stroke: "#1f5fbf", width: 1.5, points: {show: logScale}}],
      legend: {show: false},
    };
    return options;
  }

  function card(view) {
    const element = document.createElement("section");
    element.className = "channel";
    element.innerHTML =
      '<h2><span class="name"></span><span class="status"></span></h2>' +
      '<div class="frequency">&ndash;</div><div class="details"></div>' +
      '<div class="alarms"></div><div class="plots"><div class="trace"></div>' +
      '<div class="adev"></div></div>';
    document.getElementById("channels").appendChild(element);
    const width = Math.max(260, Math.floor((element.clientWidth - 30) / 2));
    const state = {
      element, time: [], frequency: [],
      trace: new uPlot(plot("deviation from the mean", "time (s)", "MHz", false, width),
                       [[], []], element.querySelector(".trace")),
      adev: new uPlot(plot("Allan deviation", "tau (s)", "Hz", true, width),
                      [[], []], element.querySelector(".adev")),
    };
    cards.set(view.channel, state);
    return state;
  }

  function show(view) {
    const state = cards.get(view.channel) || card(view);
    const element = state.element;
    text(element.querySelector(".name"), `${view.name} (channel ${view.channel})`);
    const status = element.querySelector(".status");
    text(status, view.status);
    status.className = "status " + view.status.replace(" ", "-");
    const frequency = view.frequency_hz === null ? "no reading" :
      (view.frequency_hz / 1e12).toFixed(9) + " THz";
    text(element.querySelector(".frequency"), frequency);
    const std = view.frequency_std_hz === null ? "-" : (view.frequency_std_hz / 1e6).toFixed(2);
    text(element.querySelector(".details"),
         `± ${std} MHz · flags ${view.flags} · ${view.rate_hz.toFixed(1)} readings/s · ` +
         `${view.readings} readings · sequence ${view.sequence}`);
    text(element.querySelector(".alarms"), view.alarms.join("; "));
    const trace = view.trace;
    if (trace.time_s.length) {
      state.time.push(...trace.time_s);
      state.frequency.push(...trace.frequency_hz);
      const extra = state.time.length - TRACE_POINTS;
      if (extra > 0) {
        state.time.splice(0, extra);
        state.frequency.splice(0, extra);
      }
      const mean = state.frequency.reduce((a, b) => a + b, 0) / state.frequency.length;
      const start = state.time[0];
      state.trace.setData([state.time.map((t) => t - start),
                           state.frequency.map((f) => (f - mean) / 1e6)]);
    }
    if (view.adev.tau_s.length) state.adev.setData([view.adev.tau_s, view.adev.adev_hz]);
  }

  function connect() {
    const scheme = location.protocol === "https:" ? "wss:" : "ws:";
    const suffix = token ? "?token=" + encodeURIComponent(token) : "";
    const socket = new WebSocket(`${scheme}//${location.host}/ws${suffix}`);
    socket.onopen = () => {
      text(connection, "live");
      connection.className = "state live";
      cards.forEach((state) => { state.time = []; state.frequency = []; });  // sent anew
    };
    socket.onmessage = (event) => {
      const message = JSON.parse(event.data);
      const sources = message.sources.map((s) => `${s.name}: ${s.state}`).join("; ");
      text(document.getElementById("summary"),
           `run ${message.run} · ${message.subscribers} subscriber(s) · ${sources}`);
      message.channels.forEach(show);
    };
    socket.onclose = () => {
      text(connection, "connection lost: retrying");
      connection.className = "state lost";
      setTimeout(connect, 1000);
    };
  }
  connect();
})();
