"""Limits every archive and input must stay within (docs/format.md, "Limits").

An archive comes from anywhere, so a decoder checks each size an archive declares against
these limits and against the stream that holds it before it allocates or loops. The encoder
refuses inputs beyond them, so it never writes an archive that a reader would refuse. They
sit far above real data: the longest shared clip has 5,423 frames of 62 values.
"""

MAX_FRAMES_PER_CLIP = 1 << 20  # 1,048,576 frames: 2.4 hours at 120 Hz
MAX_VALUES_PER_FRAME = 1 << 14  # AMC values per frame (CMU: 62)
MAX_VALUES_PER_CLIP = 1 << 23  # frames x values: 8,388,608 (CMU's 62 channels: 135,300 frames, 18.8 min at 120 Hz)
MAX_COEFFICIENTS_PER_MATRIX = 1 << 25  # frames x pose columns of a coded clip, pose columns x components of a basis:
#                                      a pose has up to 6 values per bone, 3 times an AMC frame's width
MAX_BONES_PER_SKELETON = 1 << 10  # ASF bones (CMU: 30); the kinematics holds a bones x bones matrix
MAX_DECODED_STREAM_BYTES = 1 << 28  # 256 MiB: what one zstd-coded stream (meta, skeletons, priors) may unpack to
MAX_PATH_BYTES = 4096  # a stored clip path or skeleton name, UTF-8
MAX_NATURAL_MODES = 8  # --model tensor: the natural modes of a class's grid (classes.modes, codec.tensor)
MAX_TENSOR_MODEL_NUMBERS = 1 << 23  # --model tensor: the numbers one model stores (mean, core, factors), 64 MiB as int64
# A decoded pose value (a joint coordinate in cm times its weight, docs/format.md) beyond this is
# no body's: a crafted model or basis whose products reach 1e124 decoded to angles that two
# correct decoders disagree on by thousands of degrees. Real poses stay below 1e7.
MAX_ABS_POSE = 1e12
