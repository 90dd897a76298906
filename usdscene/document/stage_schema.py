"""Names of the composed USD stage: layer files, prim paths and attribute names.

The composer writes these names and every reader (the Blender worker, ``scene_from_stage``,
annotation) reads them from here, so a rename happens in one place. Pure: no pxr import.

Stage layout (``out/stage/``)::

    scene.usda        root layer: sublayers strongest first, upAxis Z, metersPerUnit 1,
                      start/end time codes, customLayerData provenance
    render.usda       /Render/Settings (UsdRender.Settings), /Render/Products/<camera>
    cameras.usda      /World/Cameras/<camera>          UsdGeom.Camera + usdscene:lens:* attrs
    lights.usda       /World/Lights/<light>            UsdLux lights, variant set "lighting"
    objects.usda      /World/Objects/<class>_<uid>     references into assets, time samples,
                                                       variant set "appearance"
    environment.usda  /World/Environment               reference to the environment asset
                      /World/Environment/Places/...    its places (from the asset)
"""

from __future__ import annotations

import re

ROOT_LAYER = "scene.usda"
# Sublayers of the root, strongest first.
SUBLAYERS = ("render.usda", "cameras.usda", "lights.usda", "objects.usda", "environment.usda")

WORLD = "/World"
CAMERAS = "/World/Cameras"
LIGHTS = "/World/Lights"
OBJECTS = "/World/Objects"
ENVIRONMENT = "/World/Environment"
PLACES = "/World/Environment/Places"
RENDER_SETTINGS = "/Render/Settings"
RENDER_PRODUCTS = "/Render/Products"

# customData keys on every prim that came from an OpenLABEL element.
CUSTOM_UID = "usdscene:uid"
CUSTOM_CLASS = "usdscene:class"
CUSTOM_NAME = "usdscene:name"
# Other people's content of the element (usdscene.converters.openlabel.carry): string,
# canonical JSON of ``Camera.extra`` / ``SceneObject.extra``; absent when there is none.
CUSTOM_EXTRA = "usdscene:extra"
# string, canonical JSON {"<frame>": <carried frames[f].objects[uid] content>} of
# ``SceneObject.frame_extra`` without the per-frame pose data the pose children hold
# (FRAME_POSE_DATA); absent when there is none.
CUSTOM_FRAME_EXTRA = "usdscene:frameExtra"
# string, JSON [[frame_start, frame_end], ...]: the presence of an object or light as the
# document gives it, only when it reaches outside the stage's frame range. The visibility
# shows the range alone (and an element present on no frame of it would read back as always
# present): Scene2VCD takes the range from the visibility and the frames outside it from here.
CUSTOM_FRAME_INTERVALS = "usdscene:frameIntervals"

# The same identity as plain attributes, because Blender's USD importer drops customData but
# imports ``userProperties:*`` attributes as custom properties.
ATTR_USER_UID = "userProperties:usdscene_uid"
ATTR_USER_CLASS = "userProperties:usdscene_class"

# Camera lens attributes (on the UsdGeom.Camera prim), see usdscene.document.model.Intrinsics.
ATTR_LENS_MODEL = "usdscene:lens:model"            # token, a LensModel value
ATTR_LENS_WIDTH = "usdscene:lens:widthPx"          # int
ATTR_LENS_HEIGHT = "usdscene:lens:heightPx"        # int
ATTR_LENS_FX = "usdscene:lens:fxPx"                # double
ATTR_LENS_FY = "usdscene:lens:fyPx"                # double
ATTR_LENS_CX = "usdscene:lens:cxPx"                # double
ATTR_LENS_CY = "usdscene:lens:cyPx"                # double
ATTR_LENS_DISTORTION = "usdscene:lens:distortion"  # double[]
ATTR_LENS_FOV = "usdscene:lens:fovDeg"             # double (fisheye image-circle FOV)
ATTR_LENS_SENSOR_WIDTH = "usdscene:lens:sensorWidthMm"  # double
ATTR_CAMERA_MODEL_NAME = "usdscene:camera:modelName"    # string

# Mask id of an object prim (int, 1..65535; 0 is background), see usdscene.document.output_layout.mask_ids.
ATTR_MASK_ID = "usdscene:maskId"

# Render settings: attributes on the /Render/Settings prim, one per usdscene.document.model.RenderSettings
# field; an absent attribute means the RenderSettings default.
ATTR_RENDER_ENGINE = "usdscene:render:engine"                # token: cycles / eevee / workbench
ATTR_RENDER_DEVICE = "usdscene:render:device"                # token: cpu / gpu
ATTR_RENDER_SAMPLES = "usdscene:render:samples"              # int
ATTR_RENDER_ADAPTIVE_THRESHOLD = "usdscene:render:adaptiveThreshold"  # float, 0 = off
ATTR_RENDER_DENOISE = "usdscene:render:denoise"              # bool
ATTR_RENDER_DENOISER = "usdscene:render:denoiser"            # token
ATTR_RENDER_DENOISING_QUALITY = "usdscene:render:denoisingQuality"      # token
ATTR_RENDER_DENOISING_PREFILTER = "usdscene:render:denoisingPrefilter"  # token
ATTR_RENDER_ADAPTIVE_MIN_SAMPLES = "usdscene:render:adaptiveMinSamples"  # int, 0 = Cycles chooses
ATTR_RENDER_DENOISING_INPUT_PASSES = "usdscene:render:denoisingInputPasses"  # token
ATTR_RENDER_LIGHT_TREE = "usdscene:render:lightTree"         # bool
ATTR_RENDER_PATH_GUIDING = "usdscene:render:pathGuiding"     # bool
ATTR_RENDER_CLAMP_INDIRECT = "usdscene:render:clampIndirect"  # float, 0 = off
ATTR_RENDER_SAMPLING_PATTERN = "usdscene:render:samplingPattern"  # token
ATTR_RENDER_FAST_GI = "usdscene:render:fastGi"               # bool
ATTR_RENDER_FAST_GI_METHOD = "usdscene:render:fastGiMethod"  # token: replace / add
ATTR_RENDER_FAST_GI_AO_BOUNCES = "usdscene:render:fastGiAoBounces"  # int, 0 = no approximation
ATTR_RENDER_FAST_GI_DISTANCE = "usdscene:render:fastGiDistanceM"    # float, metres
ATTR_RENDER_SCRAMBLING_DISTANCE = "usdscene:render:scramblingDistance"  # float in [0, 1], 1 = off
ATTR_RENDER_AUTO_SCRAMBLING_DISTANCE = "usdscene:render:autoScramblingDistance"  # bool
ATTR_RENDER_MAX_BOUNCES = "usdscene:render:maxBounces"       # int
ATTR_RENDER_CAUSTICS = "usdscene:render:caustics"            # bool
ATTR_RENDER_TILE_SIZE = "usdscene:render:tileSizePx"         # int
ATTR_RENDER_RESOLUTION = "usdscene:render:resolutionPx"      # int2 (width, height)
ATTR_RENDER_SEED = "usdscene:render:seed"                    # int
ATTR_RENDER_DEPTH = "usdscene:render:depth"                  # token png16 / exr; authored only when on
# string, JSON {"world": <metadata.usdscene.world>, "hdri_path": absolute path or "",
# "sun": {"elevation_rad", "rotation_rad", "irradiance_w_m2"} or null}; only when the document
# has a world
ATTR_RENDER_WORLD = "usdscene:render:worldJson"

# Object appearance.
VARIANT_SET_APPEARANCE = "appearance"
VARIANT_SET_LIGHTING = "lighting"
ATTR_COLOR = "primvars:displayColor"

# Inside every asset of the library (relative to the asset's default prim). Blender's USD
# importer ignores inherited primvars, so recolouring goes through the main material's
# shader input: author ``<object prim>/Looks/Body/Surface.inputs:diffuseColor`` (color3f).
VARIANT_SET_POSE = "pose"                      # passengers: upright, leaning, reading, ...
VARIANT_SET_CONFIGURATION = "configuration"    # environments: e.g. bins_open / bins_closed
ASSET_LOOKS = "Looks"
ASSET_SURFACE_SHADER = "Surface"               # UsdPreviewSurface under each Material
ASSET_MAIN_MATERIAL = "Body"                   # the recolourable material of an object
ASSET_COLOR_SHADER = "Looks/Body/Surface"      # relative prim path of the colour shader
ATTR_ASSET_COLOR = "inputs:diffuseColor"       # color3f, linear RGB
# Places of an environment asset: <defaultPrim>/Places/<place>/<region>.
ATTR_KEYPOINTS = "usdscene:keypoints"           # point3f[17] on a person asset's default prim: COCO-17, asset frame
ASSET_PLACES = "Places"
ATTR_PLACE_KIND = "usdscene:place:kind"        # token on the place prim: seat, bin, aisle
ATTR_PLACE_RELATION = "usdscene:place:relation"  # token on the region prim: is_on, ...
ATTR_PLACE_SIZE = "usdscene:place:size"        # double3 on the region prim, metres

# Composition (usdscene.scene.compose) and Scene2VCD (usdscene.converters.stage.usd_stage). customData is authored
# nested ({usdscene = {uid, class, name}}), i.e. read it with prim.GetCustomDataByKey(CUSTOM_UID).
ATTR_USER_NAME = "userProperties:usdscene_name"            # string
ATTR_USER_MASK_ID = "userProperties:usdscene_mask_id"      # int, same as ATTR_MASK_ID
ATTR_USER_COLOR = "userProperties:usdscene_color"          # double3, exact linear RGB override
# Objects whose pose variant changes per frame (a walker's walk cycle, the per-frame text object
# data FRAME_POSE_DATA) get one child prim per shown variant, each referencing the asset with that
# variant selected and visible on the frames that show it; the child carries the variant's name.
FRAME_POSE_DATA = "walk_pose_variant"
POSE_CHILD_PREFIX = "pose_"
ATTR_USER_POSE = "userProperties:usdscene_pose"            # string, on a pose child prim
ATTR_CAMERA_DESCRIPTION = "usdscene:camera:description"     # string
ATTR_CAMERA_CUSTOM = "usdscene:camera:customJson"           # string, JSON of Camera.custom
# string, JSON {"sensor": <stream_properties.usdscene.sensor>, "seed": <document seed>}; only
# on cameras with a sensor
ATTR_CAMERA_SENSOR = "usdscene:camera:sensorJson"
ATTR_CAMERA_CLIPPING = "usdscene:camera:clippingRangeM"     # double2 (near, far), exact
# Lights: exact document values beside the UsdLux attributes (the Blender worker sets light
# energy from these directly).
ATTR_LIGHT_KIND = "usdscene:light:kind"                    # token: point / spot / sun / area
ATTR_LIGHT_POWER_W = "usdscene:light:powerW"               # double (sun: irradiance W/m²)
ATTR_LIGHT_COLOR = "usdscene:light:colorRgb"               # double3 linear RGB
ATTR_LIGHT_RADIUS = "usdscene:light:radiusM"               # double
ATTR_LIGHT_SPOT_ANGLE = "usdscene:light:spotAngleDeg"      # double, full cone angle
ATTR_LIGHT_SPOT_BLEND = "usdscene:light:spotBlend"         # double
ATTR_LIGHT_SIZE = "usdscene:light:sizeM"                   # double2 (width, height)
ATTR_LIGHT_SUN_ANGLE = "usdscene:light:sunAngleDeg"        # double, angular diameter
# Root layer customLayerData: dictionary "usdscene" with provenance and the document-level
# fields that have no prim (JSON strings keep their order).
LAYER_DATA_KEY = "usdscene"
# Keys of that dictionary added for other people's content: ``SceneSpec.extra`` (string,
# canonical JSON; absent when there is none). ``PlaceRef.extra`` and ``Relation.extra`` ride
# in their entries of ``placesJson`` and ``relationsJson`` as ``"extra"``.
LAYER_EXTRA = "extraJson"

# Custom properties of a Blender project written by ``usdscene blend``
# (usdscene.render.blend_io), for what Blender's USD exporter cannot carry (it writes neither
# customData nor customLayerData). On the Blender scene: the OpenLABEL document (compact JSON)
# of the scene the composed stage gives back, read back and joined with the project's cameras,
# lights and objects by ``usdscene export-openlabel scene.blend``. On each camera object: the
# camera's name in that document, so that a camera renamed in Blender keeps its content.
BLEND_DOCUMENT = "usdscene_document"
BLEND_CAMERA_NAME = "usdscene_name"

_PRIM_NAME_BAD = re.compile(r"[^A-Za-z0-9_]")


def prim_name(text: str) -> str:
    """A valid USD prim name derived from ``text`` (non-identifier characters → ``_``; a
    leading digit gets a ``_`` prefix). Deterministic; callers keep the original in
    ``customData`` so nothing is lost."""
    name = _PRIM_NAME_BAD.sub("_", text) or "_"
    if name[0].isdigit():
        name = "_" + name
    return name


def object_prim_path(class_name: str, uid: str) -> str:
    """Prim path of object ``uid`` of class ``class_name`` under ``/World/Objects``."""
    return f"{OBJECTS}/{prim_name(f'{class_name}_{uid}')}"


def camera_prim_path(camera_name: str) -> str:
    """Prim path of camera ``camera_name`` under the cameras scope."""
    return f"{CAMERAS}/{prim_name(camera_name)}"


def light_prim_path(light_name: str) -> str:
    """Prim path of light ``light_name`` under the lights scope."""
    return f"{LIGHTS}/{prim_name(light_name)}"
