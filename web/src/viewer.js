// SPDX-License-Identifier: Apache-2.0
// The point-cloud viewer: a binary PLY (docs/formats.md, point clouds: float
// x y z in mm in the main camera frame, OpenCV axes, then extra properties
// such as intensity)
// drawn as points with three.js, orbit controls, coloured by intensity or depth,
// or — the merged cloud of a 360° head, with a `camera` property named by
// `comment camera <index> <name>` header lines — by camera.

import {
  BufferAttribute,
  Color,
  PerspectiveCamera,
  Points,
  PointsMaterial,
  Scene,
  Sphere,
  Vector3,
  WebGLRenderer,
} from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { PLYLoader } from 'three/examples/jsm/loaders/PLYLoader.js';

export const BACKGROUND = 0x14181f;

// Low and high values of `values` at the given quantiles (robust to outliers).
function quantileRange(values, low = 0.01, high = 0.99) {
  const step = Math.max(1, Math.floor(values.length / 20000));
  const sample = [];
  for (let i = 0; i < values.length; i += step) {
    if (Number.isFinite(values[i])) sample.push(values[i]);
  }
  if (sample.length === 0) return [0, 1];
  sample.sort((a, b) => a - b);
  const lo = sample[Math.floor(low * (sample.length - 1))];
  const hi = sample[Math.floor(high * (sample.length - 1))];
  return hi > lo ? [lo, hi] : [lo, lo + 1];
}

// A blue → cyan → yellow → red ramp for t in [0, 1].
function ramp(t, out) {
  const stops = [
    [0.0, 0.19, 0.07, 0.55],
    [0.35, 0.1, 0.65, 0.9],
    [0.65, 0.95, 0.85, 0.2],
    [1.0, 0.85, 0.12, 0.1],
  ];
  let i = 1;
  while (i < stops.length - 1 && t > stops[i][0]) i++;
  const [t0, r0, g0, b0] = stops[i - 1];
  const [t1, r1, g1, b1] = stops[i];
  const f = Math.min(1, Math.max(0, (t - t0) / (t1 - t0)));
  out[0] = r0 + f * (r1 - r0);
  out[1] = g0 + f * (g1 - g0);
  out[2] = b0 + f * (b1 - b0);
}

// One colour per camera index (distinct hues, readable on the dark background).
export const CAMERA_COLOURS = [0x4fc3f7, 0xffb74d, 0x81c784, 0xf06292, 0xba68c8, 0xfff176, 0x4db6ac, 0xe57373];

// A value that is no camera index (a corrupt file) gets grey rather than no colour.
export function cameraColour(index) {
  return Number.isInteger(index) && index >= 0 ? CAMERA_COLOURS[index % CAMERA_COLOURS.length] : 0x9e9e9e;
}

// The `comment camera <index> <name>` lines of a PLY header: names by index.
export function plyCameraNames(bytes) {
  const head = new TextDecoder('latin1').decode(new Uint8Array(bytes, 0, Math.min(bytes.byteLength, 65536)));
  const end = head.indexOf('end_header');
  const names = [];
  for (const line of head.slice(0, end < 0 ? head.length : end).split('\n')) {
    const m = /^comment camera (\d+) (\S+)\s*$/.exec(line);
    if (m) names[Number(m[1])] = m[2];
  }
  return names;
}

// The names of the vertex properties a PLY header declares.
export function plyVertexProperties(bytes) {
  const head = new TextDecoder('latin1').decode(new Uint8Array(bytes, 0, Math.min(bytes.byteLength, 65536)));
  const end = head.indexOf('end_header');
  const names = [];
  let inVertex = false;
  for (const line of head.slice(0, end < 0 ? head.length : end).split(/\r?\n/)) {
    const words = line.trim().split(/\s+/);
    if (words[0] === 'element') inVertex = words[1] === 'vertex';
    else if (inVertex && words[0] === 'property' && words[1] !== 'list') names.push(words[words.length - 1]);
  }
  return names;
}

// The extra vertex properties the viewer uses, when the cloud has them.
const EXTRA_PROPERTIES = ['intensity', 'u', 'v', 'camera'];

// Typical distance (mm) between neighbouring points, the size a point is
// drawn with so that a surface looks closed at any zoom. Clouds of the head
// keep each point's pixel (u, v): the median distance between points of
// horizontally adjacent pixels. Otherwise a guess from the bounding sphere.
function pointSpacing(geometry) {
  const positions = geometry.getAttribute('position');
  const u = geometry.getAttribute('u');
  const v = geometry.getAttribute('v');
  const gaps = [];
  if (u && v) {
    const step = Math.max(1, Math.floor(positions.count / 20000));
    for (let i = 0; i + 1 < positions.count; i += step) {
      if (v.getX(i + 1) !== v.getX(i) || u.getX(i + 1) - u.getX(i) !== 1) continue;
      gaps.push(
        Math.hypot(
          positions.getX(i + 1) - positions.getX(i),
          positions.getY(i + 1) - positions.getY(i),
          positions.getZ(i + 1) - positions.getZ(i),
        ),
      );
    }
  }
  if (gaps.length >= 10) {
    gaps.sort((a, b) => a - b);
    return gaps[Math.floor(gaps.length / 2)];
  }
  const radius = geometry.boundingSphere ? geometry.boundingSphere.radius : 100;
  return radius * Math.sqrt(Math.PI / Math.max(1, positions.count));
}

export class PointCloudViewer {
  constructor(container) {
    this.container = container;
    this.points = null;
    this.mode = 'intensity';
    this.frameSphere = null;
    this.cameras = []; // [{index, name, points, colour}] of a cloud with a camera property
    this.renderer = new WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    this.renderer.setClearColor(new Color(BACKGROUND));
    container.appendChild(this.renderer.domElement);

    this.scene = new Scene();
    this.camera = new PerspectiveCamera(45, 1, 1, 10000);
    // OpenCV camera frame: y points down, so "up" on screen is -y.
    this.camera.up.set(0, -1, 0);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.addEventListener('change', () => this.render());

    this.resizeObserver = new ResizeObserver(() => this.resize());
    this.resizeObserver.observe(container);
    this.resize();
  }

  resize() {
    const width = this.container.clientWidth || 1;
    const height = this.container.clientHeight || 1;
    this.renderer.setSize(width, height, false);
    this.camera.aspect = width / height;
    this.camera.updateProjectionMatrix();
    this.render();
  }

  render() {
    this.renderer.render(this.scene, this.camera);
  }

  clear() {
    if (this.points) {
      this.scene.remove(this.points);
      this.points.geometry.dispose();
      this.points.material.dispose();
      this.points = null;
    }
    this.frameSphere = null;
    this.render();
  }

  // Shows the cloud of a PLY file's bytes; returns its number of points.
  load(bytes) {
    const loader = new PLYLoader();
    // Only the properties this file has: PLYLoader fills a mapped property the
    // file lacks with undefined for every vertex, which reads back as NaN (a
    // one-camera cloud would look like a merged cloud of camera "NaN").
    const present = new Set(plyVertexProperties(bytes));
    const mapping = {};
    for (const name of EXTRA_PROPERTIES) if (present.has(name)) mapping[name] = [name];
    loader.setCustomPropertyNameMapping(mapping);
    const geometry = loader.parse(bytes);
    geometry.deleteAttribute('normal');
    this.clear();
    const count = geometry.getAttribute('position').count;
    this.cameras = [];
    const camera = geometry.getAttribute('camera');
    if (camera && camera.count === count && count > 0) {
      const names = plyCameraNames(bytes);
      const counts = new Map();
      for (let i = 0; i < count; i++) counts.set(camera.getX(i), (counts.get(camera.getX(i)) || 0) + 1);
      names.forEach((name, index) => {
        if (name !== undefined && !counts.has(index)) counts.set(index, 0);
      });
      this.cameras = [...counts.keys()]
        .sort((a, b) => a - b)
        .map((index) => ({ index, name: names[index] ?? `camera ${index}`, points: counts.get(index), colour: cameraColour(index) }));
    } else if (camera) {
      geometry.deleteAttribute('camera');
    }
    geometry.setAttribute('color', new BufferAttribute(new Float32Array(count * 3), 3));
    geometry.computeBoundingSphere();
    // A point covers 1.5 spacings on screen at any distance: three.js draws an
    // attenuated point `size` × (viewport height / 2) / depth pixels wide,
    // while a length L at that depth is L × (height / 2) / (depth × tan(fov / 2)).
    const halfFov = ((this.camera.fov / 2) * Math.PI) / 180;
    const size = 1.5 * pointSpacing(geometry) / Math.tan(halfFov);
    const material = new PointsMaterial({ size, sizeAttenuation: true, vertexColors: true });
    this.points = new Points(geometry, material);
    this.scene.add(this.points);
    this.colour(this.mode);
    this.frame();
    return count;
  }

  // Colours the points by 'intensity' (normalised to its 1–99 % range; grey
  // ramp), 'depth' (z, colour ramp) or 'camera' (a merged cloud: one colour
  // per camera, its brightness by intensity). Without an intensity property:
  // depth; without a camera property, 'camera' is 'intensity'.
  colour(mode) {
    this.mode = mode;
    if (!this.points) return;
    const geometry = this.points.geometry;
    const intensity = geometry.getAttribute('intensity');
    const camera = geometry.getAttribute('camera');
    const colours = geometry.getAttribute('color');
    const out = [0, 0, 0];
    if (mode === 'camera' && camera) {
      const shade = intensity ? quantileRange(intensity.array) : null;
      const colour = new Color();
      for (let i = 0; i < camera.count; i++) {
        colour.setHex(cameraColour(camera.getX(i)));
        const g = shade ? 0.35 + 0.65 * Math.min(1, Math.max(0, (intensity.getX(i) - shade[0]) / (shade[1] - shade[0]))) : 1;
        colours.setXYZ(i, colour.r * g, colour.g * g, colour.b * g);
      }
    } else if ((mode === 'intensity' || mode === 'camera') && intensity) {
      const values = intensity.array;
      const [lo, hi] = quantileRange(values);
      for (let i = 0; i < values.length; i++) {
        const g = 0.08 + 0.92 * Math.min(1, Math.max(0, (values[i] - lo) / (hi - lo)));
        colours.setXYZ(i, g, g, g);
      }
    } else {
      const positions = geometry.getAttribute('position');
      const z = new Float32Array(positions.count);
      for (let i = 0; i < z.length; i++) z[i] = positions.getZ(i);
      const [lo, hi] = quantileRange(z);
      for (let i = 0; i < z.length; i++) {
        ramp((z[i] - lo) / (hi - lo), out);
        colours.setXYZ(i, out[0], out[1], out[2]);
      }
    }
    colours.needsUpdate = true;
    this.render();
  }

  // Looks at the cloud's bounding sphere from the camera side (−z, a little
  // off-axis), all of it in view.
  frame() {
    if (!this.points) return;
    const geometry = this.points.geometry;
    geometry.computeBoundingSphere();
    const sphere = geometry.boundingSphere || new Sphere(new Vector3(), 100);
    const radius = Math.max(sphere.radius, 1);
    const halfFov = ((this.camera.fov / 2) * Math.PI) / 180;
    const fit = Math.min(halfFov, Math.atan(Math.tan(halfFov) * this.camera.aspect));
    const distance = (radius / Math.sin(fit)) * 1.05;
    // From the head's side, turned a little so that depth shows.
    const from = new Vector3(0.35, -0.25, -1).normalize().multiplyScalar(distance);
    this.camera.position.copy(sphere.center).add(from);
    // Room to orbit and zoom out without clipping the cloud.
    this.camera.near = radius / 100;
    this.camera.far = (distance + radius) * 10;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(sphere.center);
    this.controls.update();
    this.render();
  }
}
