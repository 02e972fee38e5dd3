"""Every resource limit on what a user can hand Scanlight, stated once.

Each limit is checked before anything large is allocated: from a file's header, a JSON value or
a declared count, never after decoding. A refusal is one ScanlightError line naming the file
(exit 3). The reasons:

| limit | value | why |
|---|---|---|
| ``MAX_CAMERA_PIXELS`` | 8192 x 8192 | a camera's image (view, capture or ``render --size``); a float RGBA image of it is 1 GiB |
| ``MAX_CAMERA_SIDE`` | 16384 | one side of a camera image (a 16384-wide strip stays within the pixel limit) |
| ``MAX_CAPTURE_PIXELS`` | 2^28 | all capture images of one expansion together (6 faces per cube map); 16 cube maps of 2048^2 |
| ``MAX_COORD`` | 1e9 m | a position or translation further out is a typo, and its squares overflow float64 sums; a cloud's points beyond it are dropped with a warning, like NaN positions |
| ``MAX_RADIANCE`` | 1e15 | a colour or pixel value above it (about 10^6 times the sun's luminance in nits) is clamped to it with a warning: a float32 3e38 made the renderer's sums overflow to Inf |
| ``MAX_IMAGE_PIXELS`` | 150 Mpixel | a photo (EXR/PNG/JPEG), read from its header: 1.8 GB as linear float RGB |
| ``MAX_TEXTURE_PIXELS`` | 8192 x 8192 | one texture of a glTF or OBJ asset, read from its header |
| ``MAX_JSON_BYTES`` | 64 MiB | a camera, object, material, session or capture-cameras file (ours are a few KB) |
| ``MAX_JSON_DEPTH`` | 64 | nesting of any JSON input (camera, object, material, session, capture cameras, ``--params``, glTF); ours need 4 |
| ``MAX_PLY_HEADER`` | 1 MiB | a PLY header; the declared rows of all elements must also fit in the bytes after it |
| ``MAX_PCD_HEADER`` | 64 KiB | a PCD header |
| ``MAX_GLTF_DEPTH`` | 64 | the glTF node hierarchy (cycles are refused whatever the depth) |
| ``MAX_GLTF_INSTANCES`` | 100,000 | node instances a glTF scene expands to (a node under two parents is drawn twice; 40 levels of that is 2^40), counted before expanding |
| ``MAX_MESH_VERTICES`` | 50 M | vertices (or indices) of all instanced primitives of an asset, from the accessors' declared counts |
| ``OBJECT_SCALE`` | 1e-6 .. 1e6 | the object JSON's ``scale`` (1e308 overflowed the renderer) |

Accessor and element counts are also checked against the bytes that hold them (a PLY row takes at
least one byte; a glTF accessor must end inside its bufferView, which must end inside its
buffer). Photos narrower than 1:16 are refused by app.hdr.pipeline.validate_photo
(``MAX_PHOTO_ASPECT``): PatchMatch needs room for its patches.
"""

from __future__ import annotations

MAX_CAMERA_SIDE = 16384
MAX_CAMERA_PIXELS = 8192 * 8192
MAX_CAPTURE_PIXELS = 2 ** 28
MAX_COORD = 1e9
MAX_RADIANCE = 1e15
MAX_IMAGE_PIXELS = 150_000_000
MAX_TEXTURE_PIXELS = 8192 * 8192
MAX_JSON_BYTES = 64 << 20
MAX_JSON_DEPTH = 64
MAX_PLY_HEADER = 1 << 20
MAX_PCD_HEADER = 1 << 16
MAX_GLTF_DEPTH = 64
MAX_GLTF_INSTANCES = 100_000
MAX_MESH_VERTICES = 50_000_000
OBJECT_SCALE = (1e-6, 1e6)
