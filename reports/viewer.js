// MandiSym interactive 3D viewer: plain WebGL 1, no dependencies. Embedded in
// report.html by reports/viewer.cpp together with its data (a JSON block with
// base64 little-endian Float32 / Uint32 arrays). Coordinates arrive in the
// symmetry plane's frame: x = patient left, y = superior, z = anterior (mm,
// centred on the mesh). Sets data-viewer on #ms-viewer to "drawn" after the
// first frame, or to "no-webgl" / "error" with a message when it cannot draw.
(function () {
  'use strict';
  var root = document.getElementById('ms-viewer');
  if (!root) return;
  var canvas = root.querySelector('canvas');
  var statusBox = root.querySelector('.viewer-status');
  var labelsBox = root.querySelector('.viewer-labels');

  function fail(state, message) {
    root.setAttribute('data-viewer', state);
    statusBox.textContent = message;
    statusBox.hidden = false;
    var hide = root.querySelectorAll('.viewer-stage, .viewer-bar, .viewer-legend, .viewer-help');
    for (var i = 0; i < hide.length; i++) hide[i].hidden = true;
  }

  var data;
  try {
    data = JSON.parse(document.getElementById('ms-viewer-data').textContent);
  } catch (e) {
    fail('error', 'Interactive 3D view unavailable: its data could not be read.');
    return;
  }

  var gl = null;
  try {
    // alpha: false: an opaque canvas, so the translucent plane cannot punch through to the page.
    var opts = { alpha: false, antialias: true, preserveDrawingBuffer: true, failIfMajorPerformanceCaveat: false };
    gl = canvas.getContext('webgl', opts) || canvas.getContext('experimental-webgl', opts);
  } catch (e) {
    gl = null;
  }
  if (!gl) {
    fail('no-webgl', 'Interactive 3D view unavailable: this browser has WebGL turned off or unsupported. ' +
      'The static 3D views show the same surface.');
    return;
  }

  // ---- data ----
  function decode(b64) {
    var s = atob(b64), n = s.length, u = new Uint8Array(n);
    for (var i = 0; i < n; i++) u[i] = s.charCodeAt(i);
    return u.buffer;
  }
  var positions = new Float32Array(decode(data.positions));
  var tris32 = new Uint32Array(decode(data.triangles));
  var fields = { mirror: new Float32Array(decode(data.mirror)), saf: new Float32Array(decode(data.saf)) };
  var nv = positions.length / 3;
  var indexType, indices;
  if (nv <= 65536) {
    indices = new Uint16Array(tris32);
    indexType = gl.UNSIGNED_SHORT;
  } else if (gl.getExtension('OES_element_index_uint')) {
    indices = tris32;
    indexType = gl.UNSIGNED_INT;
  } else {
    fail('no-webgl', 'Interactive 3D view unavailable: the mesh needs 32-bit indices, which this browser lacks.');
    return;
  }

  // Area-weighted vertex normals.
  var normals = new Float32Array(positions.length);
  for (var t = 0; t < tris32.length; t += 3) {
    var a = tris32[t] * 3, b = tris32[t + 1] * 3, c = tris32[t + 2] * 3;
    var ux = positions[b] - positions[a], uy = positions[b + 1] - positions[a + 1], uz = positions[b + 2] - positions[a + 2];
    var vx = positions[c] - positions[a], vy = positions[c + 1] - positions[a + 1], vz = positions[c + 2] - positions[a + 2];
    var nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    for (var k = 0; k < 3; k++) {
      var o = tris32[t + k] * 3;
      normals[o] += nx; normals[o + 1] += ny; normals[o + 2] += nz;
    }
  }
  for (var q = 0; q < normals.length; q += 3) {
    var len = Math.sqrt(normals[q] * normals[q] + normals[q + 1] * normals[q + 1] + normals[q + 2] * normals[q + 2]) || 1;
    normals[q] /= len; normals[q + 1] /= len; normals[q + 2] /= len;
  }

  // ---- shaders ----
  var meshVS = [
    'attribute vec3 aPos; attribute vec3 aNormal; attribute float aValue;',
    'uniform mat4 uModelView; uniform mat4 uProj;',
    'varying vec3 vNormal; varying float vValue;',
    'void main() {',
    '  vNormal = mat3(uModelView) * aNormal; vValue = aValue;',
    '  gl_Position = uProj * uModelView * vec4(aPos, 1.0);',
    '}'].join('\n');
  // Same colour maps as the static views (reports/render.cpp).
  var meshFS = [
    'precision mediump float;',
    'varying vec3 vNormal; varying float vValue;',
    'uniform vec2 uRange; uniform float uDiverging;',
    'vec3 ramp(float t) {',
    '  if (uDiverging > 0.5) {',
    '    float s = 2.0 * t - 1.0;',
    '    if (s < 0.0) return vec3(1.0 + s * 0.85, 1.0 + s * 0.65, 1.0);',
    '    return vec3(1.0, 1.0 - s * 0.75, 1.0 - s * 0.85);',
    '  }',
    '  return vec3(1.0 - 0.45 * t * t, 1.0 - 0.95 * t, 1.0 - 0.95 * sqrt(t));',
    '}',
    'void main() {',
    '  float t = clamp((vValue - uRange.x) / (uRange.y - uRange.x), 0.0, 1.0);',
    '  vec3 n = normalize(vNormal);',
    '  float d = abs(dot(n, normalize(vec3(0.25, 0.35, 1.0))));',
    '  float sp = pow(max(dot(n, normalize(vec3(0.12, 0.18, 1.0))), 0.0), 24.0);',
    '  gl_FragColor = vec4(ramp(t) * (0.32 + 0.68 * d) + vec3(0.12 * sp), 1.0);',
    '}'].join('\n');
  var flatVS = [
    'attribute vec3 aPos; uniform mat4 uModelView; uniform mat4 uProj; uniform float uPointSize;',
    'void main() { gl_Position = uProj * uModelView * vec4(aPos, 1.0); gl_PointSize = uPointSize; }'].join('\n');
  var flatFS = [
    'precision mediump float; uniform vec4 uColour; uniform float uRound;',
    'void main() {',
    '  if (uRound > 0.5 && length(gl_PointCoord - vec2(0.5)) > 0.5) discard;',
    '  gl_FragColor = uColour;',
    '}'].join('\n');

  function program(vs, fs) {
    function shader(type, src) {
      var s = gl.createShader(type);
      gl.shaderSource(s, src);
      gl.compileShader(s);
      return gl.getShaderParameter(s, gl.COMPILE_STATUS) ? s : null;
    }
    var v = shader(gl.VERTEX_SHADER, vs), f = shader(gl.FRAGMENT_SHADER, fs);
    if (!v || !f) return null;
    var p = gl.createProgram();
    gl.attachShader(p, v);
    gl.attachShader(p, f);
    gl.linkProgram(p);
    return gl.getProgramParameter(p, gl.LINK_STATUS) ? p : null;
  }
  var meshProg = program(meshVS, meshFS), flatProg = program(flatVS, flatFS);
  if (!meshProg || !flatProg) {
    fail('error', 'Interactive 3D view unavailable: the graphics driver rejected its shaders.');
    return;
  }

  function buffer(target, array) {
    var b = gl.createBuffer();
    gl.bindBuffer(target, b);
    gl.bufferData(target, array, gl.STATIC_DRAW);
    return b;
  }
  var posBuf = buffer(gl.ARRAY_BUFFER, positions);
  var normBuf = buffer(gl.ARRAY_BUFFER, normals);
  var valueBufs = { mirror: buffer(gl.ARRAY_BUFFER, fields.mirror), saf: buffer(gl.ARRAY_BUFFER, fields.saf) };
  var idxBuf = buffer(gl.ELEMENT_ARRAY_BUFFER, indices);

  var lm = data.landmarks || [];
  var lmPos = new Float32Array(lm.length * 3);
  for (var i = 0; i < lm.length; i++) { lmPos[3 * i] = lm[i].p[0]; lmPos[3 * i + 1] = lm[i].p[1]; lmPos[3 * i + 2] = lm[i].p[2]; }
  var lmBuf = buffer(gl.ARRAY_BUFFER, lmPos);
  var px = data.plane_x, ph = 0.5 * data.size, pw = 0.6 * data.size;
  var planeBuf = buffer(gl.ARRAY_BUFFER, new Float32Array([
    px, -ph, -pw, px, -ph, pw, px, ph, pw,
    px, -ph, -pw, px, ph, pw, px, ph, -pw]));

  var labelEls = [];
  for (var j = 0; j < lm.length; j++) {
    var el = document.createElement('span');
    el.textContent = lm[j].name;
    labelsBox.appendChild(el);
    labelEls.push(el);
  }

  // ---- camera ----
  var deg = Math.PI / 180;
  // [yaw, pitch]; "oblique" (the initial view and reset) shows the front, the
  // left side and the plane at once.
  var presets = {
    oblique: [-35 * deg, 12 * deg], front: [0, 0], below: [0, -90 * deg], left: [-90 * deg, 0], right: [90 * deg, 0]
  };
  var cam = {};
  function reset(view) {
    var p = presets[view] || presets.oblique;
    cam.yaw = p[0]; cam.pitch = p[1]; cam.panX = 0; cam.panY = 0;
    cam.dist = data.size * 1.9;
  }
  reset('oblique');

  function mul(a, b) {  // column-major 4x4
    var r = new Float32Array(16);
    for (var col = 0; col < 4; col++)
      for (var row = 0; row < 4; row++) {
        var s = 0;
        for (var k2 = 0; k2 < 4; k2++) s += a[k2 * 4 + row] * b[col * 4 + k2];
        r[col * 4 + row] = s;
      }
    return r;
  }
  function rotX(t) { var c = Math.cos(t), s = Math.sin(t); return new Float32Array([1, 0, 0, 0, 0, c, s, 0, 0, -s, c, 0, 0, 0, 0, 1]); }
  function rotY(t) { var c = Math.cos(t), s = Math.sin(t); return new Float32Array([c, 0, -s, 0, 0, 1, 0, 0, s, 0, c, 0, 0, 0, 0, 1]); }
  function translate(x, y, z) { return new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, x, y, z, 1]); }
  function perspective(fovy, aspect, near, far) {
    var f = 1 / Math.tan(fovy / 2), nf = 1 / (near - far);
    return new Float32Array([f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0]);
  }

  // ---- state and drawing ----
  var state = { field: 'mirror', landmarks: true, plane: true };
  var ranges = { mirror: data.mirror_range, saf: data.saf_range };

  function attrib(prog, name, buf, size) {
    var loc = gl.getAttribLocation(prog, name);
    if (loc < 0) return -1;
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.enableVertexAttribArray(loc);
    gl.vertexAttribPointer(loc, size, gl.FLOAT, false, 0, 0);
    return loc;
  }
  function resize() {
    var dpr = window.devicePixelRatio || 1;
    var w = Math.max(1, Math.round(canvas.clientWidth * dpr)), h = Math.max(1, Math.round(canvas.clientHeight * dpr));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  }

  function draw() {
    resize();
    var w = canvas.width, h = canvas.height;
    gl.viewport(0, 0, w, h);
    gl.clearColor(1, 1, 1, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    var proj = perspective(30 * deg, w / h, cam.dist * 0.05, cam.dist * 10);
    var mv = mul(translate(cam.panX, cam.panY, -cam.dist), mul(rotX(cam.pitch), rotY(cam.yaw)));

    gl.useProgram(meshProg);
    var locs = [attrib(meshProg, 'aPos', posBuf, 3), attrib(meshProg, 'aNormal', normBuf, 3),
      attrib(meshProg, 'aValue', valueBufs[state.field], 1)];
    gl.uniformMatrix4fv(gl.getUniformLocation(meshProg, 'uModelView'), false, mv);
    gl.uniformMatrix4fv(gl.getUniformLocation(meshProg, 'uProj'), false, proj);
    var r = ranges[state.field];
    gl.uniform2f(gl.getUniformLocation(meshProg, 'uRange'), r[0], r[1]);
    gl.uniform1f(gl.getUniformLocation(meshProg, 'uDiverging'), state.field === 'mirror' ? 1 : 0);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, idxBuf);
    gl.drawElements(gl.TRIANGLES, indices.length, indexType, 0);
    for (var a2 = 0; a2 < locs.length; a2++) if (locs[a2] >= 0) gl.disableVertexAttribArray(locs[a2]);

    gl.useProgram(flatProg);
    gl.uniformMatrix4fv(gl.getUniformLocation(flatProg, 'uModelView'), false, mv);
    gl.uniformMatrix4fv(gl.getUniformLocation(flatProg, 'uProj'), false, proj);
    var uColour = gl.getUniformLocation(flatProg, 'uColour'), uRound = gl.getUniformLocation(flatProg, 'uRound');
    var uSize = gl.getUniformLocation(flatProg, 'uPointSize');
    if (state.plane) {
      var pl = attrib(flatProg, 'aPos', planeBuf, 3);
      gl.enable(gl.BLEND);
      gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA);
      gl.depthMask(false);
      gl.uniform4f(uColour, 0.35, 0.45, 0.65, 0.2);
      gl.uniform1f(uRound, 0);
      gl.uniform1f(uSize, 1);
      gl.drawArrays(gl.TRIANGLES, 0, 6);
      gl.depthMask(true);
      gl.disable(gl.BLEND);
      gl.disableVertexAttribArray(pl);
    }
    if (state.landmarks && lm.length) {
      var lp = attrib(flatProg, 'aPos', lmBuf, 3);
      gl.disable(gl.DEPTH_TEST);  // landmarks and their labels stay visible from every side
      gl.uniform4f(uColour, 0.08, 0.5, 0.18, 1);
      gl.uniform1f(uRound, 1);
      gl.uniform1f(uSize, 9 * (window.devicePixelRatio || 1));
      gl.drawArrays(gl.POINTS, 0, lm.length);
      gl.enable(gl.DEPTH_TEST);
      gl.disableVertexAttribArray(lp);
    }
    placeLabels(mul(proj, mv));
  }

  function placeLabels(m) {
    var cw = canvas.clientWidth, ch = canvas.clientHeight;
    for (var i2 = 0; i2 < lm.length; i2++) {
      var p = lm[i2].p, el2 = labelEls[i2];
      var x = m[0] * p[0] + m[4] * p[1] + m[8] * p[2] + m[12];
      var y = m[1] * p[0] + m[5] * p[1] + m[9] * p[2] + m[13];
      var wc = m[3] * p[0] + m[7] * p[1] + m[11] * p[2] + m[15];
      var visible = state.landmarks && wc > 0;
      el2.hidden = !visible;
      if (!visible) continue;
      el2.style.left = ((x / wc * 0.5 + 0.5) * cw + 6) + 'px';
      el2.style.top = ((0.5 - y / wc * 0.5) * ch - 8) + 'px';
    }
  }

  var pending = false;
  function redraw() {
    if (pending) return;
    pending = true;
    window.requestAnimationFrame(function () { pending = false; draw(); });
  }

  // ---- legend ----
  var rampEl = root.querySelector('.viewer-ramp'), ticks = root.querySelectorAll('.viewer-ticks span');
  var captionEl = root.querySelector('.viewer-caption');
  function cssColour(t, diverging) {
    var r2, g2, b2;
    if (diverging) {
      var s = 2 * t - 1;
      if (s < 0) { r2 = 1 + s * 0.85; g2 = 1 + s * 0.65; b2 = 1; } else { r2 = 1; g2 = 1 - s * 0.75; b2 = 1 - s * 0.85; }
    } else { r2 = 1 - 0.45 * t * t; g2 = 1 - 0.95 * t; b2 = 1 - 0.95 * Math.sqrt(t); }
    return 'rgb(' + Math.round(255 * r2) + ',' + Math.round(255 * g2) + ',' + Math.round(255 * b2) + ')';
  }
  function legend() {
    var diverging = state.field === 'mirror', r3 = ranges[state.field], stops = [];
    for (var s = 0; s <= 10; s++) stops.push(cssColour(s / 10, diverging) + ' ' + (s * 10) + '%');
    rampEl.style.background = 'linear-gradient(to right, ' + stops.join(', ') + ')';
    var mid = (r3[0] + r3[1]) / 2;
    var fmt = function (v) { return (Math.abs(v) < 1e-9 ? 0 : v).toFixed(diverging ? 1 : 2); };
    ticks[0].textContent = fmt(r3[0]);
    ticks[1].textContent = fmt(mid);
    ticks[2].textContent = (diverging ? '+' : '') + fmt(r3[1]);
    captionEl.textContent = diverging ?
      'Signed mirror distance (mm): red where this side bulges beyond its mirror image, blue where it lies inside it.' :
      'SAF map, sided (rad): where the two sides differ in shape, shown on the side that lies beyond its mirror image.';
  }

  // ---- controls ----
  var radios = root.querySelectorAll('input[name="ms-colour"]');
  for (var ri = 0; ri < radios.length; ri++)
    radios[ri].addEventListener('change', function (e) { state.field = e.target.value; legend(); redraw(); });
  root.querySelector('#ms-show-landmarks').addEventListener('change', function (e) { state.landmarks = e.target.checked; redraw(); });
  root.querySelector('#ms-show-plane').addEventListener('change', function (e) { state.plane = e.target.checked; redraw(); });
  var viewButtons = root.querySelectorAll('button[data-view]');
  for (var vb = 0; vb < viewButtons.length; vb++)
    viewButtons[vb].addEventListener('click', function (e) { reset(e.currentTarget.getAttribute('data-view')); redraw(); });

  var drag = null;
  canvas.addEventListener('contextmenu', function (e) { e.preventDefault(); });
  canvas.addEventListener('pointerdown', function (e) {
    drag = { x: e.clientX, y: e.clientY, pan: e.button !== 0 || e.shiftKey };
    canvas.setPointerCapture(e.pointerId);
    e.preventDefault();
  });
  canvas.addEventListener('pointermove', function (e) {
    if (!drag) return;
    var dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX; drag.y = e.clientY;
    if (drag.pan) {
      var perPixel = 2 * cam.dist * Math.tan(15 * deg) / Math.max(1, canvas.clientHeight);
      cam.panX += dx * perPixel; cam.panY -= dy * perPixel;
    } else {
      cam.yaw += dx * 0.01;
      cam.pitch = Math.max(-Math.PI, Math.min(Math.PI, cam.pitch + dy * 0.01));
    }
    redraw();
  });
  function endDrag() { drag = null; }
  canvas.addEventListener('pointerup', endDrag);
  canvas.addEventListener('pointercancel', endDrag);
  canvas.addEventListener('wheel', function (e) {
    e.preventDefault();
    cam.dist = Math.max(data.size * 0.3, Math.min(data.size * 8, cam.dist * Math.exp(e.deltaY * 0.001)));
    redraw();
  }, { passive: false });
  window.addEventListener('resize', redraw);
  canvas.addEventListener('webglcontextlost', function (e) {
    e.preventDefault();
    fail('error', 'Interactive 3D view stopped: the browser lost the WebGL context. Reload the page to restore it.');
  });

  legend();
  draw();
  if (gl.getError() === gl.NO_ERROR) {
    root.setAttribute('data-viewer', 'drawn');
  } else {
    root.setAttribute('data-viewer', 'error');
    statusBox.textContent = 'The interactive 3D view reported a graphics error; what it shows may be incomplete.';
    statusBox.hidden = false;
  }
})();
