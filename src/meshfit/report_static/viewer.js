// The report's 3D view: the displaced surface from the GLB that report/model.js holds
// (base64, window.MESHFIT_MODEL), coloured by its deviation from the scan, drawn with the
// three.js bundle (three.min.js, global MeshfitThree). A classic script: pages opened from
// file:// may not load ES modules or fetch files, so nothing here is fetched.
//
// The page gives the element #view3d with data-views (JSON: [{name, view, up}], the fixed
// viewpoints of the static renders) and data-background (CSS colour). When the model is
// drawn, #view3d gets data-state="ready" (or "failed" with the reason in .view3d-status).
(function () {
  "use strict";
  var box = document.getElementById("view3d");
  if (!box) return;
  var status = box.querySelector(".view3d-status");
  var readout = box.querySelector(".view3d-readout");

  function fail(reason) {
    box.dataset.state = "failed";
    if (status) status.textContent = "3D view unavailable: " + reason;
  }

  var T = window.MeshfitThree;
  if (!T) return fail("the three.js bundle (report/three.min.js) did not load");
  if (!window.MESHFIT_MODEL) return fail("the model (report/model.js) did not load");

  function decode(b64) {
    var text = atob(b64);
    var bytes = new Uint8Array(text.length);
    for (var i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
    return bytes.buffer;
  }

  var canvas = box.querySelector("canvas");
  var renderer;
  try {
    // the drawing buffer is kept so that the picture can be read back (tests, saving)
    renderer = new T.WebGLRenderer({ canvas: canvas, antialias: true, preserveDrawingBuffer: true });
  } catch (err) {
    return fail("WebGL is not available in this browser (" + err.message + ")");
  }
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setClearColor(new T.Color(box.dataset.background || "#ffffff"));
  var scene = new T.Scene();
  var camera = new T.PerspectiveCamera(30, 1, 0.01, 100);
  scene.add(new T.AmbientLight(0xffffff, 0.45));
  var headlight = new T.DirectionalLight(0xffffff, 1.6);
  scene.add(headlight);
  scene.add(headlight.target);
  var controls = new T.OrbitControls(camera, canvas);
  controls.enableDamping = false;

  var views = JSON.parse(box.dataset.views || "[]");
  var centre = new T.Vector3();
  var radius = 1;
  var meshes = [];

  function resize() {
    var w = canvas.clientWidth;
    var h = canvas.clientHeight;
    if (canvas.width !== Math.floor(w * renderer.getPixelRatio()) ||
        canvas.height !== Math.floor(h * renderer.getPixelRatio())) {
      renderer.setSize(w, h, false);
      camera.aspect = w / Math.max(h, 1);
      camera.updateProjectionMatrix();
    }
  }

  function draw() {
    resize();
    // a head light: from the camera towards what it looks at
    headlight.position.copy(camera.position);
    headlight.target.position.copy(controls.target);
    headlight.target.updateMatrixWorld();
    renderer.render(scene, camera);
  }

  function show(k) {
    var v = views[k];
    if (!v) return;
    var d = new T.Vector3(v.view[0], v.view[1], v.view[2]).normalize();
    var dist = (radius / Math.sin((camera.fov * Math.PI) / 360)) * 0.8;
    camera.up.set(v.up[0], v.up[1], v.up[2]);
    camera.position.copy(centre).addScaledVector(d, -dist);
    camera.near = dist / 100;
    camera.far = dist * 10;
    camera.updateProjectionMatrix();
    controls.target.copy(centre);
    controls.update();
    draw();
  }

  // the model as a file, for other viewers: the bytes the page holds, saved by the browser
  var save = box.querySelector("button.view3d-save");
  if (save) {
    save.addEventListener("click", function () {
      var url = URL.createObjectURL(new Blob([decode(window.MESHFIT_MODEL)], { type: "model/gltf-binary" }));
      var a = document.createElement("a");
      a.href = url;
      a.download = "model.glb";
      document.body.appendChild(a);
      a.click();
      a.remove();
      setTimeout(function () { URL.revokeObjectURL(url); }, 1000);
    });
  }

  var buttons = box.querySelectorAll("button[data-view]");
  buttons.forEach(function (b) {
    b.addEventListener("click", function () { show(Number(b.dataset.view)); });
  });
  controls.addEventListener("change", draw);
  window.addEventListener("resize", draw);

  // the patch and the deviation under the pointer (the nearest corner of the hit triangle)
  var ray = new T.Raycaster();
  var pointer = new T.Vector2();
  canvas.addEventListener("pointermove", function (ev) {
    if (!readout || !meshes.length) return;
    var r = canvas.getBoundingClientRect();
    pointer.set(((ev.clientX - r.left) / r.width) * 2 - 1, -((ev.clientY - r.top) / r.height) * 2 + 1);
    ray.setFromCamera(pointer, camera);
    var hit = ray.intersectObjects(meshes, false)[0];
    if (!hit || !hit.face) {
      readout.textContent = "";
      return;
    }
    var dev = hit.object.geometry.getAttribute("_deviation");
    var face = hit.face;
    var pos = hit.object.geometry.getAttribute("position");
    var best = face.a;
    var bestD = Infinity;
    [face.a, face.b, face.c].forEach(function (i) {
      var p = new T.Vector3().fromBufferAttribute(pos, i);
      var dd = p.distanceToSquared(hit.point);
      if (dd < bestD) { bestD = dd; best = i; }
    });
    var text = hit.object.name;
    if (dev) text += ": deviation " + dev.getX(best).toPrecision(3) + "% of the bbox diagonal";
    readout.textContent = text;
  });

  new T.GLTFLoader().parse(decode(window.MESHFIT_MODEL), "", function (gltf) {
    var material = new T.MeshLambertMaterial({ vertexColors: true, side: T.DoubleSide });
    gltf.scene.traverse(function (o) {
      if (o.isMesh) {
        o.geometry.computeVertexNormals();
        o.material = material;
        meshes.push(o);
      }
    });
    scene.add(gltf.scene);
    var bounds = new T.Box3().setFromObject(gltf.scene);
    bounds.getCenter(centre);
    radius = Math.max(bounds.getSize(new T.Vector3()).length() / 2, 1e-12);
    show(0);
    box.dataset.state = "ready";
    if (status) status.textContent = "";
  }, function (err) {
    fail("the model could not be read (" + (err && err.message ? err.message : err) + ")");
  });
})();
