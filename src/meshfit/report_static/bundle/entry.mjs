// The parts of three.js the report's 3D view uses, bundled as one classic script
// (a global ``MeshfitThree``): pages opened from file:// cannot import ES modules.
export {
  AmbientLight,
  Box3,
  Color,
  DirectionalLight,
  MeshLambertMaterial,
  PerspectiveCamera,
  Raycaster,
  REVISION,
  Scene,
  SRGBColorSpace,
  Vector2,
  Vector3,
  WebGLRenderer,
  DoubleSide,
} from "three";
export { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
export { OrbitControls } from "three/addons/controls/OrbitControls.js";
