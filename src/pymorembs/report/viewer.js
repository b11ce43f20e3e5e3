/* pymorembs 3D viewer: a body's surface, nodes, frame, interfaces and shape functions.
 *
 * Dependency-free WebGL 1. Usage:
 *   const v = new PymorembsViewer(canvas, scene);   // scene: pymorembs.report.scene.body_scene
 *   v.setShape(0); v.setAmplitude(0.05); v.animate(true);
 *   v.setDecorations({frame, interfaces});  // new triad and interface markers, same view
 *
 * Drawing: the surface triangles flat-shaded (Lambert, a head light), their feature edges
 * (boundary edges and edges where the surface folds by more than 30 degrees), line elements,
 * nodes as points where the body has no triangles, the frame as an axis triad, interface nodes
 * as large points and their coupled nodes as coloured points. A shape is shown as
 *   x = x0 + s * u,   s = amplitude * size * sin(2 pi t / period)   (animated) or the peak,
 * with u the shape scaled to a largest translation of 1, formed in the vertex shader from two
 * buffers over the nodes (x0 and u): showing a shape writes u once, animating changes one
 * uniform. Surface, edges and lines are drawn indexed from those node buffers (one draw call
 * each); the faces' normals are those of the drawn (deformed) triangles, from the screen-space
 * derivatives of the position (OES_standard_derivatives), so they need no buffer. Feature edges
 * come from the undeformed triangles' normals, computed here once per scene.
 *
 * Mouse: left drag rotates, wheel zooms, right drag (or shift + left drag, middle drag) pans.
 */
(function (global) {
  "use strict";

  const RAMP = `
vec3 ramp(float t) {  // blue (no translation) - grey - red (the largest)
  vec3 a = vec3(0.23, 0.30, 0.75), b = vec3(0.87, 0.87, 0.87), c = vec3(0.71, 0.02, 0.15);
  return t < 0.5 ? mix(a, b, 2.0 * t) : mix(b, c, 2.0 * t - 1.0);
}`;
  // The surface's colour: the shape's translation, or a value per node of the shape (aValue.x,
  // 0..1, e.g. its von Mises stress) where the shape gives one (uValues).
  const SURFACE_VS = `
attribute vec3 aBase; attribute vec3 aShape; attribute vec3 aValue;
uniform mat4 uView; uniform mat4 uProj; uniform float uS; uniform float uValues;
varying vec3 vPos; varying float vMag;
void main() {
  vec4 p = uView * vec4(aBase + uS * aShape, 1.0);
  vPos = p.xyz;
  vMag = uValues > 0.5 ? aValue.x : length(aShape);
  gl_Position = uProj * p;
}`;
  const SURFACE_FS = `
#extension GL_OES_standard_derivatives : enable
#ifdef GL_FRAGMENT_PRECISION_HIGH
precision highp float;
#else
precision mediump float;
#endif
varying vec3 vPos; varying float vMag;
uniform vec3 uColor; uniform float uContour;
${RAMP}
void main() {
  vec3 n = normalize(cross(dFdx(vPos), dFdy(vPos)));  // the drawn triangle's, towards the eye
  if (n.z < 0.0) n = -n;
  vec3 light = normalize(vec3(0.25, 0.35, 1.0));
  float diffuse = max(dot(n, light), 0.0);
  vec3 base = uContour > 0.5 ? ramp(clamp(vMag, 0.0, 1.0)) : uColor;
  gl_FragColor = vec4(base * (0.4 + 0.6 * diffuse), 1.0);
}`;
  // Lines and points: the per-vertex colour (aColor) of the small coloured sets, or the
  // magnitude of the shape (vMag) for sets drawn from the node buffers in one colour.
  const LINE_VS = `
attribute vec3 aBase; attribute vec3 aShape; attribute vec3 aColor;
uniform mat4 uView; uniform mat4 uProj; uniform float uS; uniform float uSize;
varying vec3 vColor; varying float vMag;
void main() {
  vColor = aColor;
  vMag = length(aShape);
  gl_Position = uProj * uView * vec4(aBase + uS * aShape, 1.0);
  gl_PointSize = uSize;
}`;
  const LINE_FS = `
precision mediump float;
varying vec3 vColor;
void main() { gl_FragColor = vec4(vColor, 1.0); }`;
  const WIRE_FS = `
precision mediump float;
varying float vMag;
uniform vec3 uColor; uniform float uRound; uniform float uContour;
${RAMP}
void main() {
  if (uRound > 0.5) {
    vec2 d = gl_PointCoord - vec2(0.5);
    if (dot(d, d) > 0.25) discard;
  }
  gl_FragColor = vec4(uContour > 0.5 ? 0.8 * ramp(clamp(vMag, 0.0, 1.0)) : uColor, 1.0);
}`;
  const POINT_FS = `
precision mediump float;
varying vec3 vColor;
void main() {
  vec2 d = gl_PointCoord - vec2(0.5);
  float r = dot(d, d);
  if (r > 0.25) discard;
  gl_FragColor = vec4(r > 0.16 ? vColor * 0.45 : vColor, 1.0);
}`;

  const COLORS = {
    background: [0.97, 0.975, 0.98],
    body: [0.50, 0.62, 0.80],
    edge: [0.16, 0.19, 0.25],
    line: [0.10, 0.25, 0.55],
    node: [0.15, 0.30, 0.60],
    axes: [[0.85, 0.1, 0.1], [0.1, 0.6, 0.1], [0.1, 0.2, 0.9]],
  };
  // Interface colours (node and its coupled nodes), cycling.
  const PALETTE = [
    [0.90, 0.45, 0.0], [0.75, 0.0, 0.65], [0.0, 0.62, 0.62], [0.85, 0.72, 0.0],
    [0.45, 0.25, 0.0], [0.95, 0.25, 0.45],
  ];
  const FEATURE_COS = Math.cos(30 * Math.PI / 180);
  const FOV = 30 * Math.PI / 180;
  const PERIOD_S = 2.0;
  const TRIAD = 0.2;  // length of the frame's axes, fraction of the size

  function css(rgb) {
    return "rgb(" + rgb.map((c) => Math.round(255 * c)).join(",") + ")";
  }

  function unitColor(rgb) {
    const c = Array.from(rgb || [1, 0, 0], Number);
    return c.some((x) => x > 1) ? c.map((x) => x / 255) : c;
  }

  function compile(gl, vs, fs) {
    const program = gl.createProgram();
    for (const [type, text] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
      const shader = gl.createShader(type);
      gl.shaderSource(shader, text);
      gl.compileShader(shader);
      if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) {
        throw new Error("PymorembsViewer: shader: " + gl.getShaderInfoLog(shader));
      }
      gl.attachShader(program, shader);
    }
    gl.linkProgram(program);
    if (!gl.getProgramParameter(program, gl.LINK_STATUS)) {
      throw new Error("PymorembsViewer: program: " + gl.getProgramInfoLog(program));
    }
    const info = { program, attributes: {}, uniforms: {} };
    const na = gl.getProgramParameter(program, gl.ACTIVE_ATTRIBUTES);
    for (let i = 0; i < na; i++) {
      const name = gl.getActiveAttrib(program, i).name;
      info.attributes[name] = gl.getAttribLocation(program, name);
    }
    const nu = gl.getProgramParameter(program, gl.ACTIVE_UNIFORMS);
    for (let i = 0; i < nu; i++) {
      const name = gl.getActiveUniform(program, i).name;
      info.uniforms[name] = gl.getUniformLocation(program, name);
    }
    return info;
  }

  // 3x3 matrices row-major in arrays of 9.
  function mul3(a, b) {
    const out = new Array(9);
    for (let i = 0; i < 3; i++) {
      for (let j = 0; j < 3; j++) {
        out[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j];
      }
    }
    return out;
  }
  function rotX(a) {
    const c = Math.cos(a), s = Math.sin(a);
    return [1, 0, 0, 0, c, -s, 0, s, c];
  }
  function rotY(a) {
    const c = Math.cos(a), s = Math.sin(a);
    return [c, 0, s, 0, 1, 0, -s, 0, c];
  }
  function orthonormal(r) {
    // Gram-Schmidt on the rows, so that rounding never shears the view.
    const x = [r[0], r[1], r[2]], y = [r[3], r[4], r[5]];
    const nx = Math.hypot(...x);
    for (let k = 0; k < 3; k++) x[k] /= nx;
    const d = x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    for (let k = 0; k < 3; k++) y[k] -= d * x[k];
    const ny = Math.hypot(...y);
    for (let k = 0; k < 3; k++) y[k] /= ny;
    const z = [x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]];
    return [...x, ...y, ...z];
  }

  class PymorembsViewer {
    /**
     * @param {HTMLCanvasElement} canvas
     * @param {object} scene  the dict of pymorembs.report.scene.body_scene
     * @param {object} [options]  {legend: true}: draw a legend next to the canvas
     */
    constructor(canvas, scene, options) {
      this.canvas = canvas;
      this.options = Object.assign({ legend: true }, options || {});
      const attributes = { antialias: true, preserveDrawingBuffer: true };
      const gl = canvas.getContext("webgl", attributes) ||
        canvas.getContext("experimental-webgl", attributes);
      if (!gl) throw new Error("PymorembsViewer: this browser offers no WebGL");
      this.gl = gl;
      this.frames = 0;
      if (!gl.getExtension("OES_standard_derivatives")) {
        throw new Error("PymorembsViewer: this browser's WebGL lacks OES_standard_derivatives");
      }
      this._uint = !!gl.getExtension("OES_element_index_uint");
      this._programs = {
        surface: compile(gl, SURFACE_VS, SURFACE_FS),
        wire: compile(gl, LINE_VS, WIRE_FS),
        line: compile(gl, LINE_VS, LINE_FS),
        point: compile(gl, LINE_VS, POINT_FS),
      };
      this._buffers = {};
      this._shape = null;
      this._amplitude = 0.05;
      this._animating = false;
      this._contour = true;
      this._start = performance.now();
      this._highlights = [];
      this._listeners = [];
      this._pending = false;
      this._dpr = global.devicePixelRatio || 1;
      this._bindMouse();
      this.setScene(scene);
    }

    // ------------------------------------------------------------------ public
    /** Index of the shown shape, or null. */
    get shape() {
      return this._shape;
    }

    /** Largest translation of the shown shape as a fraction of the model's size. */
    get amplitude() {
      return this._amplitude;
    }

    /** Whether the shape is animated. */
    get animating() {
      return this._animating;
    }

    /** Call `listener(viewer)` after every change of scene, shape, amplitude or animation. */
    onChange(listener) {
      this._listeners.push(listener);
    }

    /** Replace the scene (resets shape, highlights and view). */
    setScene(scene) {
      this.scene = scene;
      const P = new Float32Array(scene.positions || []);
      this._n = P.length / 3;
      if (this._n > 65536 && !this._uint) {
        throw new Error("PymorembsViewer: this browser's WebGL draws at most 65,536 nodes " +
          "(no OES_element_index_uint); the scene has " + this._n);
      }
      this._P = P;
      this._tri = Uint32Array.from(scene.triangles || []);
      this._lin = Uint32Array.from(scene.lines || []);
      this._size = scene.size > 0 ? scene.size : 1;
      this._U = new Float32Array(3 * this._n);  // the shown shape, largest translation 1
      this._values = new Float32Array(3 * this._n);  // its values per node (x), largest 1
      this._valued = false;
      this._shape = null;
      this._highlights = [];
      this._bounds();
      this._buildSurface();
      this._buildEdges();
      this._buildPoints();
      this._buildTriad();
      this._shapeBuffers();
      this.resetView();
      this._changed();
    }

    /** Replace the frame triad and the interface markers with their coupled nodes, keeping
     * the view, the shown shape and the highlights. `decorations`: `{frame, interfaces}` as in
     * the scene (a key left out keeps what is drawn); an interface may give `position` [x, y, z]
     * (model length unit) where its marker goes, for a node the scene lacks (e.g. one the user
     * is adding): `{name, node: index | null, position, coupled: [indices]}`. */
    setDecorations(decorations) {
      const d = decorations || {};
      if ("frame" in d) this.scene.frame = d.frame || null;
      if ("interfaces" in d) this.scene.interfaces = Array.from(d.interfaces || []);
      this._bounds();  // for the next resetView; the camera stays
      this._buildPoints();
      this._buildTriad();
      this._changed();
      this._requestRender();
    }

    /** Show shape k (index into scene.shapes), or the undeformed body for null. A shape with
     * `scalars` (one number per node, e.g. its von Mises stress) colours the surface by them
     * (largest 1) instead of by its translation. */
    setShape(k) {
      const shapes = this.scene.shapes || [];
      this._valued = false;
      this._values.fill(0);
      if (!Number.isInteger(k) || k < 0 || k >= shapes.length) {
        this._shape = null;
        this._U.fill(0);
      } else {
        const scalars = shapes[k].scalars;
        if (scalars && scalars.length === this._n) {
          let top = 0;
          for (let i = 0; i < this._n; i++) top = Math.max(top, Math.abs(scalars[i]) || 0);
          for (let i = 0; i < this._n; i++) this._values[3 * i] = top > 0 ? (scalars[i] || 0) / top : 0;
          this._valued = true;
        }
        this._shape = k;
        const v = shapes[k].values;
        let peak = 0;
        for (let i = 0; i < this._n; i++) {
          peak = Math.max(peak, Math.hypot(v[3 * i], v[3 * i + 1], v[3 * i + 2]));
        }
        const f = peak > 0 ? 1 / peak : 0;
        for (let i = 0; i < 3 * this._n; i++) this._U[i] = f * v[i];
      }
      this._shapeBuffers();
      this._changed();
      this._requestRender();
    }

    /** Largest translation of the shown shape as a fraction of the model's size. */
    setAmplitude(a) {
      this._amplitude = Math.max(0, Number(a) || 0);
      this._changed();
      this._requestRender();
    }

    /** Colour the surface by the shape's translation (true, default) or plainly. */
    setContour(on) {
      this._contour = !!on;
      this._changed();
      this._requestRender();
    }

    /** Run (true) or stop (false) the sin(t) animation of the shown shape. */
    animate(on) {
      on = !!on;
      if (on === this._animating) return;
      this._animating = on;
      this._start = performance.now();
      this._changed();
      if (on) {
        const loop = () => {
          if (!this._animating) return;
          this.render();
          global.requestAnimationFrame(loop);
        };
        global.requestAnimationFrame(loop);
      } else {
        this._requestRender();
      }
    }

    /** Mark nodes (indices into the scene's nodes) in a colour [r, g, b] (0..1 or 0..255). */
    highlight(indices, color) {
      this._highlights.push({ indices: Array.from(indices || []), color: unitColor(color) });
      this._buildHighlights();
      this._requestRender();
    }

    clearHighlight() {
      this._highlights = [];
      this._buildHighlights();
      this._requestRender();
    }

    /** The whole body in view, from the default direction. */
    resetView() {
      const e = this._extent;
      const axes = [0, 1, 2].sort((a, b) => e[b] - e[a]);  // longest first
      const row = (k) => [0, 1, 2].map((j) => (j === k ? 1 : 0));
      const x = row(axes[0]), z = row(axes[2]);
      const y = [z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]];
      this._R = orthonormal(mul3(mul3(rotX(0.4), rotY(-0.5)), [...x, ...y, ...z]));
      this._center = this._middle.slice();
      this._distance = this._fitDistance();
      this._requestRender();
    }

    /** Index of the node under the cursor (nearest of the triangle hit, else the nearest drawn
     * node within 10 px), or null. */
    pickNode(clientX, clientY) {
      const hit = this._rayHit(clientX, clientY);
      const X = this._current();
      if (hit) {
        let best = null, bestD = Infinity;
        for (let c = 0; c < 3; c++) {
          const i = this._tri[3 * hit.triangle + c];
          const d = Math.hypot(X[3 * i] - hit.point[0], X[3 * i + 1] - hit.point[1],
            X[3 * i + 2] - hit.point[2]);
          if (d < bestD) { bestD = d; best = i; }
        }
        return best;
      }
      const [px, py] = this._canvasPixel(clientX, clientY);
      const m = this._matrices();
      const w = this.canvas.width, h = this.canvas.height;
      const limit = 10 * this._dpr;
      let best = null, bestD = limit * limit, bestZ = Infinity;
      for (let i = 0; i < this._n; i++) {
        const q = project(m.pv, X[3 * i], X[3 * i + 1], X[3 * i + 2]);
        if (!q) continue;
        const sx = (q[0] + 1) * 0.5 * w, sy = (1 - q[1]) * 0.5 * h;
        const d = (sx - px) * (sx - px) + (sy - py) * (sy - py);
        if (d < bestD - 1e-9 || (d <= bestD && q[2] < bestZ)) { bestD = d; bestZ = q[2]; best = i; }
      }
      return best;
    }

    /** Index of the surface triangle under the cursor (the nearest one hit), or null. */
    pickTriangle(clientX, clientY) {
      const hit = this._rayHit(clientX, clientY);
      return hit ? hit.triangle : null;
    }

    /** Draw one frame now. */
    render() {
      const gl = this.gl;
      this._resize();
      const m = this._matrices();
      const s = this._deflection();
      const bg = COLORS.background;
      gl.viewport(0, 0, this.canvas.width, this.canvas.height);
      gl.clearColor(bg[0], bg[1], bg[2], 1);
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      gl.enable(gl.DEPTH_TEST);
      gl.depthFunc(gl.LEQUAL);
      const b = this._buffers;
      if (b.surface && b.surface.count) {
        const p = this._use("surface", m, s);
        gl.uniform3fv(p.uniforms.uColor, COLORS.body);
        gl.uniform1f(p.uniforms.uContour, this._contour && this._shape !== null ? 1 : 0);
        gl.uniform1f(p.uniforms.uValues, this._valued ? 1 : 0);
        gl.enable(gl.POLYGON_OFFSET_FILL);
        gl.polygonOffset(1, 1);
        this._draw(p, b.surface, gl.TRIANGLES);
        gl.disable(gl.POLYGON_OFFSET_FILL);
      }
      const dpr = this._dpr;
      const wires = [["edges", gl.LINES, COLORS.edge], ["lines", gl.LINES, COLORS.line],
        ["nodes", gl.POINTS, COLORS.node]];
      for (const [kind, mode, color] of wires) {
        if (!b[kind] || !b[kind].count) continue;
        const p = this._use("wire", m, s);
        gl.uniform3fv(p.uniforms.uColor, color);
        gl.uniform1f(p.uniforms.uSize, 4 * dpr);
        gl.uniform1f(p.uniforms.uRound, mode === gl.POINTS ? 1 : 0);
        const contour = kind !== "edges" && this._contour && this._shape !== null;
        gl.uniform1f(p.uniforms.uContour, contour ? 1 : 0);
        this._draw(p, b[kind], mode);
      }
      const pointSets = [["coupled", 6], ["highlight", 7]];
      for (const [kind, size] of pointSets) {
        if (!b[kind] || !b[kind].count) continue;
        const p = this._use("point", m, s);
        gl.uniform1f(p.uniforms.uSize, size * dpr);
        this._draw(p, b[kind], gl.POINTS);
      }
      gl.disable(gl.DEPTH_TEST);  // frame and interface nodes stay visible inside the body
      if (b.triad && b.triad.count) this._draw(this._use("line", m, 0), b.triad, gl.LINES);
      if (b.interfaces && b.interfaces.count) {
        const p = this._use("point", m, s);
        gl.uniform1f(p.uniforms.uSize, 13 * dpr);
        this._draw(p, b.interfaces, gl.POINTS);
      }
      this.frames += 1;
    }

    /** Build a shape selector, amplitude slider, animation switch and view reset into
     * `container`; returns the elements. */
    static controls(viewer, container) {
      const doc = container.ownerDocument;
      const make = (tag, props) => Object.assign(doc.createElement(tag), props || {});
      const label = (text, element) => {
        const l = make("label");
        l.style.marginRight = "1em";
        l.append(text + " ", element);
        container.append(l);
        return element;
      };
      const select = make("select");
      let listed = null;  // the scene whose shapes the selector lists
      const list = () => {
        listed = viewer.scene;
        select.textContent = "";
        select.append(make("option", { value: "", textContent: "undeformed" }));
        (listed.shapes || []).forEach((shape, k) => {
          select.append(make("option", { value: String(k), textContent: shape.name }));
        });
      };
      list();
      label("shape", select);
      const amplitude = make("input", { type: "range", min: "0", max: "0.25", step: "0.005",
        value: String(viewer._amplitude) });
      label("amplitude", amplitude);
      const run = make("input", { type: "checkbox", checked: viewer._animating });
      label("animate", run);
      const contour = make("input", { type: "checkbox", checked: viewer._contour });
      label("colour by translation", contour);
      const reset = make("button", { type: "button", textContent: "reset view" });
      container.append(reset);
      select.addEventListener("change", () => {
        viewer.setShape(select.value === "" ? null : Number(select.value));
      });
      amplitude.addEventListener("input", () => viewer.setAmplitude(Number(amplitude.value)));
      run.addEventListener("change", () => viewer.animate(run.checked));
      contour.addEventListener("change", () => viewer.setContour(contour.checked));
      reset.addEventListener("click", () => viewer.resetView());
      const sync = () => {
        if (listed !== viewer.scene) list();
        select.value = viewer._shape === null ? "" : String(viewer._shape);
        amplitude.value = String(viewer._amplitude);
        run.checked = viewer._animating;
        contour.checked = viewer._contour;
      };
      viewer.onChange(sync);
      return { select, amplitude, run, contour, reset, sync };
    }

    // ------------------------------------------------------------------ geometry
    _bounds() {
      const P = this._P, n = this._n;
      const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
      for (let i = 0; i < n; i++) {
        for (let k = 0; k < 3; k++) {
          const x = P[3 * i + k];
          if (x < lo[k]) lo[k] = x;
          if (x > hi[k]) hi[k] = x;
        }
      }
      if (!n) { lo.fill(-0.5); hi.fill(0.5); }
      const f = this.scene.frame;
      if (f) {  // the triad belongs in the view too
        const L = TRIAD * this._size;
        for (const tip of [[0, 0, 0], ...f.axes]) {
          for (let k = 0; k < 3; k++) {
            const x = f.origin[k] + L * tip[k];
            lo[k] = Math.min(lo[k], x);
            hi[k] = Math.max(hi[k], x);
          }
        }
      }
      for (const f of this.scene.interfaces || []) {  // markers off the scene's nodes
        if (!f.position) continue;
        for (let k = 0; k < 3; k++) {
          lo[k] = Math.min(lo[k], Number(f.position[k]));
          hi[k] = Math.max(hi[k], Number(f.position[k]));
        }
      }
      this._lo = lo;
      this._hi = hi;
      this._middle = [0, 1, 2].map((k) => 0.5 * (lo[k] + hi[k]));
      this._extent = [0, 1, 2].map((k) => hi[k] - lo[k]);
    }

    _buildSurface() {
      // The node buffers (x0, and u of the shown shape) and the triangles' index buffer.
      const old = this._buffers.node || {};
      this._buffers.node = {
        aBase: this._upload(old.aBase, this._P),
        aShape: this._upload(old.aShape, this._U),
        aValue: this._upload(old.aValue, this._values),
      };
      this._buffers.surface = this._indexBuffer(this._buffers.surface, this._tri);
    }

    _indexBuffer(old, indices) {
      const gl = this.gl;
      const buffer = (old && old.indices) || gl.createBuffer();
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, buffer);
      const typed = this._uint ? Uint32Array.from(indices) : Uint16Array.from(indices);
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, typed, gl.STATIC_DRAW);
      return { count: indices.length, indices: buffer };
    }

    _triangleNormals() {
      // Unit normal of every undeformed triangle, shape (t, 3) flat.
      const T = this._tri, t = T.length / 3, P = this._P, N = new Float32Array(3 * t);
      for (let j = 0; j < t; j++) {
        const a = 3 * T[3 * j], b = 3 * T[3 * j + 1], c = 3 * T[3 * j + 2];
        const nn = cross([P[b] - P[a], P[b + 1] - P[a + 1], P[b + 2] - P[a + 2]],
          [P[c] - P[a], P[c + 1] - P[a + 1], P[c + 2] - P[a + 2]]);
        const len = Math.hypot(nn[0], nn[1], nn[2]) || 1;
        N[3 * j] = nn[0] / len; N[3 * j + 1] = nn[1] / len; N[3 * j + 2] = nn[2] / len;
      }
      return N;
    }

    _buildEdges() {
      // Feature edges: on the boundary, on a fold of more than 30 degrees (either orientation:
      // shells need not be oriented alike), or with three triangles and more. The triangle
      // sides are bucketed by their lower node (counting sort), so equal sides meet in a
      // bucket of a few entries: linear in the number of triangles.
      const T = this._tri, t = T.length / 3, n = this._n, N = this._triangleNormals();
      const sides = 3 * t, start = new Uint32Array(n + 1);
      for (let e = 0; e < sides; e++) {
        const a = T[e], b = T[e - (e % 3) + ((e % 3) + 1) % 3];
        start[Math.min(a, b) + 1] += 1;
      }
      for (let i = 0; i < n; i++) start[i + 1] += start[i];
      const fill = start.slice(0, n), upper = new Uint32Array(sides), owner = new Uint32Array(sides);
      for (let e = 0; e < sides; e++) {
        const a = T[e], b = T[e - (e % 3) + ((e % 3) + 1) % 3];
        const at = fill[Math.min(a, b)]++;
        upper[at] = Math.max(a, b);
        owner[at] = (e - (e % 3)) / 3;
      }
      const edges = [];
      for (let i = 0; i < n; i++) {
        for (let x = start[i]; x < start[i + 1]; x++) {
          const b = upper[x];
          let count = 0, other = -1, seen = false;
          for (let y = start[i]; y < start[i + 1]; y++) {
            if (upper[y] !== b) continue;
            if (y < x) { seen = true; break; }  // this side was judged at its first entry
            count += 1;
            if (y > x && other < 0) other = owner[y];
          }
          if (seen) continue;
          let feature = count !== 2;
          if (count === 2) {
            const j = owner[x];
            const d = N[3 * j] * N[3 * other] + N[3 * j + 1] * N[3 * other + 1] +
              N[3 * j + 2] * N[3 * other + 2];
            feature = Math.abs(d) < FEATURE_COS;
          }
          if (feature) edges.push(i, b);
        }
      }
      this._buffers.edges = this._indexBuffer(this._buffers.edges, edges);
      this._buffers.lines = this._indexBuffer(this._buffers.lines, this._lin);
    }

    _buildPoints() {
      const s = this.scene;
      // Without triangles every node is a point, drawn straight from the node buffers.
      this._buffers.nodes = { count: this._tri.length === 0 ? this._n : 0, all: true };
      const coupled = [], coupledColor = [], nodes = [], nodeColor = [], where = [];
      const known = (i) => Number.isInteger(i) && i >= 0 && i < this._n;
      (s.interfaces || []).forEach((f, k) => {
        const c = PALETTE[k % PALETTE.length];
        for (const i of f.coupled || []) {
          if (known(i)) { coupled.push(i); coupledColor.push(c); }
        }
        // The marker: at the given position, else at the node; it follows the node's shape.
        const i = known(f.node) ? f.node : -1;
        const p = f.position && f.position.length === 3 ? Array.from(f.position, Number) : null;
        if (i < 0 && !p) return;
        nodes.push(i);
        where.push(p);
        nodeColor.push(c);
      });
      this._coupledSet = Uint32Array.from(coupled);
      this._buffers.coupled = this._pointBuffer(this._buffers.coupled, this._coupledSet,
        (k) => coupledColor[k]);
      this._interfaceSet = Int32Array.from(nodes);
      this._buffers.interfaces = this._pointBuffer(this._buffers.interfaces,
        this._interfaceSet, (k) => nodeColor[k], where);
      this._buildHighlights();
    }

    _buildHighlights() {
      const nodes = [], colors = [];
      for (const h of this._highlights) {
        for (const i of h.indices) {
          if (i >= 0 && i < this._n) { nodes.push(i); colors.push(h.color); }
        }
      }
      this._highlightSet = Uint32Array.from(nodes);
      this._buffers.highlight = this._pointBuffer(this._buffers.highlight, this._highlightSet,
        (k) => colors[k]);
    }

    _buildTriad() {
      const f = this.scene.frame;
      if (!f) { this._buffers.triad = { count: 0 }; return; }
      const L = TRIAD * this._size;
      const base = [], color = [];
      f.axes.forEach((axis, k) => {
        base.push(...f.origin, ...f.origin.map((o, j) => o + L * axis[j]));
        color.push(...COLORS.axes[k], ...COLORS.axes[k]);
      });
      const old = this._buffers.triad || {};
      this._buffers.triad = {
        count: 6,
        aBase: this._upload(old.aBase, new Float32Array(base)),
        aShape: this._upload(old.aShape, new Float32Array(18)),
        aColor: this._upload(old.aColor, new Float32Array(color)),
      };
    }

    _segmentBuffer(old, nodes, rgb, where) {
      // where[v]: the position of vertex v instead of its node's (null: the node's).
      const m = nodes.length, base = new Float32Array(3 * m), color = new Float32Array(3 * m);
      for (let v = 0; v < m; v++) {
        const i = nodes[v], p = where && where[v];
        for (let k = 0; k < 3; k++) {
          base[3 * v + k] = p ? p[k] : this._P[3 * i + k];
          color[3 * v + k] = rgb[k];
        }
      }
      old = old || {};
      return {
        count: m, nodes,
        aBase: this._upload(old.aBase, base),
        aShape: this._upload(old.aShape, this._gather(nodes)),
        aColor: this._upload(old.aColor, color),
      };
    }

    _pointBuffer(old, nodes, colorOf, where) {
      const buffer = this._segmentBuffer(old, nodes, [0, 0, 0], where);
      const color = new Float32Array(3 * nodes.length);
      for (let v = 0; v < nodes.length; v++) color.set(colorOf(v), 3 * v);
      this._upload(buffer.aColor, color);
      return buffer;
    }

    _gather(nodes) {
      const out = new Float32Array(3 * nodes.length), U = this._U;
      for (let v = 0; v < nodes.length; v++) {
        const i = nodes[v];
        if (i < 0) continue;  // a marker off the scene's nodes: it stays where it is
        out[3 * v] = U[3 * i]; out[3 * v + 1] = U[3 * i + 1]; out[3 * v + 2] = U[3 * i + 2];
      }
      return out;
    }

    _shapeBuffers() {
      // The shown shape into the node buffer, and into the few coloured points' buffers.
      if (this._buffers.node) {
        this._upload(this._buffers.node.aShape, this._U);
        this._upload(this._buffers.node.aValue, this._values);
      }
      for (const kind of ["coupled", "interfaces", "highlight"]) {
        const b = this._buffers[kind];
        if (b && b.nodes) this._upload(b.aShape, this._gather(b.nodes));
      }
    }

    _upload(buffer, data) {
      const gl = this.gl;
      buffer = buffer || gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
      gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
      return buffer;
    }

    // ------------------------------------------------------------------ drawing
    _deflection() {
      if (this._shape === null) return 0;
      const s = this._amplitude * this._size;
      if (!this._animating) return s;
      const t = (performance.now() - this._start) / 1000;
      return s * Math.sin(2 * Math.PI * t / PERIOD_S);
    }

    _resize() {
      const c = this.canvas, dpr = this._dpr;
      const w = Math.max(1, Math.round((c.clientWidth || c.width) * dpr));
      const h = Math.max(1, Math.round((c.clientHeight || c.height) * dpr));
      if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
    }

    _fitDistance() {
      const R = this._R, lo = this._lo, hi = this._hi, mid = this._middle;
      let hw = 0, hh = 0, hd = 0;
      for (let corner = 0; corner < 8; corner++) {
        const p = [0, 1, 2].map((k) => ((corner >> k) & 1 ? hi[k] : lo[k]) - mid[k]);
        hw = Math.max(hw, Math.abs(R[0] * p[0] + R[1] * p[1] + R[2] * p[2]));
        hh = Math.max(hh, Math.abs(R[3] * p[0] + R[4] * p[1] + R[5] * p[2]));
        hd = Math.max(hd, Math.abs(R[6] * p[0] + R[7] * p[1] + R[8] * p[2]));
      }
      const c = this.canvas;
      const aspect = (c.clientWidth || c.width) / (c.clientHeight || c.height) || 1;
      const ty = Math.tan(FOV / 2), tx = ty * aspect;
      const d = 1.15 * Math.max(hh / ty, hw / tx) + hd;
      return d > 0 ? d : this._size;
    }

    _matrices() {
      const R = this._R, c = this._center, d = this._distance;
      const view = new Float32Array(16);
      for (let i = 0; i < 3; i++) {
        for (let j = 0; j < 3; j++) view[4 * j + i] = R[3 * i + j];
        view[12 + i] = -(R[3 * i] * c[0] + R[3 * i + 1] * c[1] + R[3 * i + 2] * c[2]);
      }
      view[14] -= d;
      view[15] = 1;
      const w = this.canvas.width, h = this.canvas.height;
      const aspect = w / h || 1, f = 1 / Math.tan(FOV / 2);
      const reach = 2 * this._size + 1e-12;
      const near = Math.max(d - reach, d * 1e-3), far = d + reach;
      const proj = new Float32Array(16);
      proj[0] = f / aspect;
      proj[5] = f;
      proj[10] = (far + near) / (near - far);
      proj[11] = -1;
      proj[14] = 2 * far * near / (near - far);
      return { view, proj, pv: mul4(proj, view), aspect };
    }

    _use(name, m, s) {
      const gl = this.gl, p = this._programs[name];
      gl.useProgram(p.program);
      gl.uniformMatrix4fv(p.uniforms.uView, false, m.view);
      gl.uniformMatrix4fv(p.uniforms.uProj, false, m.proj);
      gl.uniform1f(p.uniforms.uS, s);
      return p;
    }

    _draw(p, set, mode) {
      // A set with `indices` or `all` draws from the node buffers, others from their own.
      const gl = this.gl, source = set.indices || set.all ? this._buffers.node : set;
      const used = [];
      for (const name in p.attributes) {
        const location = p.attributes[name];
        if (!source[name]) continue;  // e.g. aColor of a one-colour set: a constant
        gl.bindBuffer(gl.ARRAY_BUFFER, source[name]);
        gl.enableVertexAttribArray(location);
        gl.vertexAttribPointer(location, 3, gl.FLOAT, false, 0, 0);
        used.push(location);
      }
      if (set.indices) {
        gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, set.indices);
        gl.drawElements(mode, set.count, this._uint ? gl.UNSIGNED_INT : gl.UNSIGNED_SHORT, 0);
      } else {
        gl.drawArrays(mode, 0, set.count);
      }
      for (const location of used) gl.disableVertexAttribArray(location);
    }

    _requestRender() {
      if (this._animating || this._pending) return;
      this._pending = true;
      global.requestAnimationFrame(() => {
        this._pending = false;
        if (!this._animating) this.render();
      });
    }

    // ------------------------------------------------------------------ picking
    _current() {
      const s = this._deflection(), P = this._P, U = this._U;
      if (s === 0) return P;
      const X = new Float32Array(P.length);
      for (let i = 0; i < P.length; i++) X[i] = P[i] + s * U[i];
      return X;
    }

    _canvasPixel(clientX, clientY) {
      const r = this.canvas.getBoundingClientRect();
      return [(clientX - r.left) / (r.width || 1) * this.canvas.width,
        (clientY - r.top) / (r.height || 1) * this.canvas.height];
    }

    _rayHit(clientX, clientY) {
      const T = this._tri, t = T.length / 3;
      if (!t) return null;
      const [px, py] = this._canvasPixel(clientX, clientY);
      const w = this.canvas.width, h = this.canvas.height;
      const ty = Math.tan(FOV / 2), aspect = w / h || 1;
      const vx = ((2 * px) / w - 1) * ty * aspect, vy = (1 - (2 * py) / h) * ty;
      const R = this._R, c = this._center, d = this._distance;
      // Eye and ray direction in world coordinates: R^T of the view-space vectors.
      const eye = [0, 1, 2].map((k) => c[k] + R[6 + k] * d);
      const dir = [0, 1, 2].map((k) => R[k] * vx + R[3 + k] * vy - R[6 + k]);
      const X = this._current();
      let best = Infinity, bestJ = -1;
      for (let j = 0; j < t; j++) {
        const a = 3 * T[3 * j], b = 3 * T[3 * j + 1], cc = 3 * T[3 * j + 2];
        const e1x = X[b] - X[a], e1y = X[b + 1] - X[a + 1], e1z = X[b + 2] - X[a + 2];
        const e2x = X[cc] - X[a], e2y = X[cc + 1] - X[a + 1], e2z = X[cc + 2] - X[a + 2];
        const qx = dir[1] * e2z - dir[2] * e2y, qy = dir[2] * e2x - dir[0] * e2z;
        const qz = dir[0] * e2y - dir[1] * e2x;
        const det = e1x * qx + e1y * qy + e1z * qz;
        if (det === 0) continue;
        const inv = 1 / det;
        const sx = eye[0] - X[a], sy = eye[1] - X[a + 1], sz = eye[2] - X[a + 2];
        const u = (sx * qx + sy * qy + sz * qz) * inv;
        if (u < 0 || u > 1) continue;
        const rx = sy * e1z - sz * e1y, ry = sz * e1x - sx * e1z, rz = sx * e1y - sy * e1x;
        const v = (dir[0] * rx + dir[1] * ry + dir[2] * rz) * inv;
        if (v < 0 || u + v > 1) continue;
        const along = (e2x * rx + e2y * ry + e2z * rz) * inv;
        if (along > 0 && along < best) { best = along; bestJ = j; }
      }
      if (bestJ < 0) return null;
      return { triangle: bestJ, point: [0, 1, 2].map((k) => eye[k] + best * dir[k]) };
    }

    // ------------------------------------------------------------------ mouse
    _bindMouse() {
      const c = this.canvas;
      let last = null, mode = null;
      c.addEventListener("contextmenu", (e) => e.preventDefault());
      c.addEventListener("mousedown", (e) => {
        mode = e.button === 2 || e.button === 1 || e.shiftKey ? "pan" : "rotate";
        last = [e.clientX, e.clientY];
        e.preventDefault();
      });
      global.addEventListener("mouseup", () => { mode = null; });
      global.addEventListener("mousemove", (e) => {
        if (!mode) return;
        const dx = e.clientX - last[0], dy = e.clientY - last[1];
        last = [e.clientX, e.clientY];
        if (mode === "rotate") {
          this._R = orthonormal(mul3(mul3(rotY(0.01 * dx), rotX(0.01 * dy)), this._R));
        } else {
          const r = c.getBoundingClientRect();
          const scale = 2 * this._distance * Math.tan(FOV / 2) / (r.height || 1);
          const R = this._R;
          for (let k = 0; k < 3; k++) this._center[k] -= scale * (dx * R[k] - dy * R[3 + k]);
        }
        this._requestRender();
      });
      c.addEventListener("wheel", (e) => {
        e.preventDefault();
        const step = e.deltaMode === 1 ? 40 * e.deltaY : e.deltaY;
        this._distance *= Math.exp(Math.max(-1, Math.min(1, 0.0015 * step)));
        this._requestRender();
      }, { passive: false });
    }

    // ------------------------------------------------------------------ legend
    _changed() {
      this._legend();
      for (const listener of this._listeners) listener(this);
    }

    _legend() {
      if (!this.options.legend) return;
      const c = this.canvas, parent = c.parentNode;
      if (!parent) return;
      const doc = c.ownerDocument;
      if (!this._legendBox) {
        if (global.getComputedStyle(parent).position === "static") {
          parent.style.position = "relative";
        }
        this._legendBox = doc.createElement("div");
        this._legendBox.className = "pymorembs-legend";
        Object.assign(this._legendBox.style, {
          position: "absolute", left: "8px", top: "8px", padding: "4px 8px",
          background: "rgba(255,255,255,0.85)", font: "12px system-ui, sans-serif",
          border: "1px solid #ccc", pointerEvents: "none", lineHeight: "1.5",
        });
        c.insertAdjacentElement("afterend", this._legendBox);
      }
      const box = this._legendBox;
      box.textContent = "";
      const item = (rgb, text, round) => {
        const row = doc.createElement("div");
        const swatch = doc.createElement("span");
        Object.assign(swatch.style, {
          display: "inline-block", width: "10px", height: "10px", marginRight: "6px",
          background: css(rgb), borderRadius: round ? "50%" : "0", verticalAlign: "middle",
        });
        row.append(swatch, text);
        box.append(row);
      };
      const s = this.scene;
      if (this._tri.length) item(COLORS.body, "surface");
      if (this._lin.length) item(COLORS.line, "line elements");
      if (!this._tri.length) item(COLORS.node, "nodes", true);
      (s.interfaces || []).forEach((f, k) => {
        item(PALETTE[k % PALETTE.length], f.name + " and its " + (f.coupled || []).length +
          " coupled nodes", true);
      });
      if (s.frame) {
        const row = doc.createElement("div");
        row.append("frame: ");
        ["x", "y", "z"].forEach((name, k) => {
          const span = doc.createElement("span");
          span.style.color = css(COLORS.axes[k]);
          span.style.fontWeight = "bold";
          span.textContent = name + " ";
          row.append(span);
        });
        box.append(row);
      }
      if (this._shape !== null) {
        const row = doc.createElement("div");
        row.textContent = s.shapes[this._shape].name + ", largest translation " +
          (100 * this._amplitude).toFixed(1) + " % of the size";
        box.append(row);
      }
    }
  }

  function cross(a, b) {
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  }

  function mul4(a, b) {  // column-major 4x4 product a * b
    const out = new Float32Array(16);
    for (let i = 0; i < 4; i++) {
      for (let j = 0; j < 4; j++) {
        let sum = 0;
        for (let k = 0; k < 4; k++) sum += a[4 * k + i] * b[4 * j + k];
        out[4 * j + i] = sum;
      }
    }
    return out;
  }

  function project(m, x, y, z) {  // clip -> normalised device coordinates, null behind the eye
    const w = m[3] * x + m[7] * y + m[11] * z + m[15];
    if (w <= 0) return null;
    return [(m[0] * x + m[4] * y + m[8] * z + m[12]) / w,
      (m[1] * x + m[5] * y + m[9] * z + m[13]) / w,
      (m[2] * x + m[6] * y + m[10] * z + m[14]) / w];
  }

  global.PymorembsViewer = PymorembsViewer;
})(typeof window !== "undefined" ? window : globalThis);
