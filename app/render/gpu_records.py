"""CPU<->GPU records declared once: one ordered field list gives the numpy dtype (how Python packs
and reads a record) and the GLSL that decodes it (generated includes, see programs.py).

Why: a record that crosses between Python and a shader is otherwise written twice - column
indexes and byte counts in numpy, ``.xyz`` / ``[4u * i + 2u]`` in GLSL - and nothing notices
when the two drift apart. Declared here, a field moves in both at once, and the tests decode
every record on the GPU through the generated code (tests/pbgi/test_gpu_records.py).

A ``Record`` is a sequence of 32-bit *words* grouped in *slots* of ``slot_words`` words: the unit
GLSL reads at once (4: one vec4 / uvec4 SSBO element or image texel; 2: an RG texel; 1: a plain
float / uint array, or a vertex). Fields follow each other in declaration order; with slots of
more than one word a field never straddles two (it is one swizzle of one load), and ``Pad``
fills the rest of a slot. Each field has a GLSL type (float, uint,
int, vecN, uvecN, ivecN); the storage's base type is ``word`` (float or uint). A field whose base
type differs from the storage's keeps its bits (``floatBitsToUint``) unless it is declared
``stored_as="value"``: an integer held as a float *value* (a material id written by a float
render target), decoded as ``uint(x + 0.5)``.

What the generated GLSL can be (each record picks what its users need):

* ``glsl_getters``: one function per field, ``position(i)`` reading slot k of record i from an
  expression the caller gives (an SSBO array, a texelFetch);
* ``glsl_struct`` + ``glsl_unpack`` / ``glsl_pack``: a struct and its conversion from / to the
  slot vectors (image texels);
* ``glsl_word_defines``: ``#define PREFIX_FIELD word`` for records used as a word array with
  atomics (counters);
* a struct used as the SSBO element itself: valid std430 when every field is a 32-bit scalar
  (``std430_struct_ok``), so the struct *is* the layout;
* ``glsl_vertex_inputs`` / ``vertex_format``: a vertex buffer's attributes and moderngl format
  (``vertex_content`` / ``field_array``: the same record kept in one buffer per field).

Texel records also give their texture's components, moderngl dtype and GLSL image format.
``Units`` is the same idea for binding points: one table, ``#define``s for the shaders.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# GLSL type -> (base type, components)
_GLSL_TYPES = {"float": ("float", 1), "uint": ("uint", 1), "int": ("int", 1)}
for _n in (2, 3, 4):
    _GLSL_TYPES[f"vec{_n}"] = ("float", _n)
    _GLSL_TYPES[f"uvec{_n}"] = ("uint", _n)
    _GLSL_TYPES[f"ivec{_n}"] = ("int", _n)
_NUMPY = {"float": np.float32, "uint": np.uint32, "int": np.int32}
_VEC = {"float": "vec", "uint": "uvec", "int": "ivec"}
_MODERNGL = {"float": "f", "uint": "u", "int": "i"}     # moderngl buffer format letters
# bit-preserving conversions GLSL[(from, to)]
_BITS = {("float", "uint"): "floatBitsToUint", ("float", "int"): "floatBitsToInt",
         ("uint", "float"): "uintBitsToFloat", ("int", "float"): "intBitsToFloat",
         ("uint", "int"): "int", ("int", "uint"): "uint"}
_SWIZZLE = "xyzw"


def glsl_vector(base: str, n: int) -> str:
    """``vec3``, ``uint``, ... for a base type and a component count."""
    return base if n == 1 else f"{_VEC[base]}{n}"


@dataclass(frozen=True)
class Field:
    """One field: ``name``, GLSL ``type``, ``doc`` (what it holds - goes into the GLSL comments),
    ``stored_as``: None (its own bits) or "value" (an integer held as a float value)."""

    name: str
    type: str
    doc: str = ""
    stored_as: str | None = None

    @property
    def base(self) -> str:
        return _GLSL_TYPES[self.type][0]

    @property
    def comps(self) -> int:
        return _GLSL_TYPES[self.type][1]


@dataclass(frozen=True)
class Pad:
    """``words`` unused words (zero), e.g. the rest of a slot."""

    words: int = 1


class Record:
    """A record layout (see the module docstring). ``name``: the GLSL struct name; ``word``: the
    storage's base type ("float" or "uint"); ``slot_words``: 4 (vec4 / uvec4 slots) or 1;
    ``words``: total words (default: the fields rounded up to whole slots)."""

    def __init__(self, name: str, items, *, word: str = "float", slot_words: int = 4,
                 words: int | None = None, doc: str = ""):
        if word not in ("float", "uint"):
            raise ValueError(f"{name}: storage word must be float or uint, got {word!r}")
        self.name, self.word, self.slot_words, self.doc = name, word, int(slot_words), doc
        self.fields: list[Field] = []
        self._word_of: dict[str, int] = {}
        w = 0
        for item in items:
            if isinstance(item, Pad):
                w += item.words
                continue
            if item.type not in _GLSL_TYPES:
                raise ValueError(f"{name}.{item.name}: unknown GLSL type {item.type!r}")
            if item.stored_as not in (None, "value"):
                raise ValueError(f"{name}.{item.name}: stored_as must be None or 'value'")
            if item.stored_as == "value" and (word != "float" or item.type != "uint"):
                raise ValueError(f"{name}.{item.name}: only a uint can be stored as a float value")
            if item.name in self._word_of:
                raise ValueError(f"{name}: field {item.name!r} declared twice")
            if (self.slot_words > 1
                    and w // self.slot_words != (w + item.comps - 1) // self.slot_words):
                raise ValueError(f"{name}.{item.name}: straddles slot {w // self.slot_words}")
            self.fields.append(item)
            self._word_of[item.name] = w
            w += item.comps
        total = -(-w // self.slot_words) * self.slot_words if words is None else int(words)
        if total < w or total % self.slot_words:
            raise ValueError(f"{name}: {total} words cannot hold {w} in slots of {slot_words}")
        self.words = total
        self.dtype = self._make_dtype()

    # -- Python -----------------------------------------------------------------------------
    @property
    def nbytes(self) -> int:
        return 4 * self.words

    @property
    def slots(self) -> int:
        return self.words // self.slot_words

    def field(self, name: str) -> Field:
        return self.fields[list(self._word_of).index(name)]

    def index(self, name: str) -> int:
        """First word of a field within the record."""
        return self._word_of[name]

    def slot(self, name: str) -> int:
        return self._word_of[name] // self.slot_words

    def _numpy_base(self, f: Field):
        return _NUMPY["float" if f.stored_as == "value" else f.base]

    def _make_dtype(self) -> np.dtype:
        names, formats, offsets = [], [], []
        for f in self.fields:
            names.append(f.name)
            base = self._numpy_base(f)
            formats.append((base, (f.comps,)) if f.comps > 1 else base)
            offsets.append(4 * self._word_of[f.name])
        return np.dtype({"names": names, "formats": formats, "offsets": offsets,
                         "itemsize": self.nbytes})

    @property
    def word_dtype(self):
        return np.dtype(_NUMPY[self.word])

    def zeros(self, n: int) -> np.ndarray:
        """``n`` records, every word 0 (padding included), as a structured array."""
        return np.zeros(int(n), dtype=self.dtype)

    def view(self, data) -> np.ndarray:
        """Records (structured, 1-D) over bytes or any contiguous array of whole records -
        no copy where the input allows it."""
        if isinstance(data, (bytes, bytearray, memoryview)):
            return np.frombuffer(data, dtype=self.dtype)
        a = np.ascontiguousarray(data)
        if a.dtype == self.dtype:
            return a.reshape(-1)
        return a.reshape(-1).view(np.uint8).view(self.dtype)

    def flat(self, records: np.ndarray) -> np.ndarray:
        """Records as an (n, words) array of the storage type (a view)."""
        r = np.ascontiguousarray(records)
        return r.view(self.word_dtype).reshape(len(r), self.words)

    def columns(self, name: str) -> slice:
        """The columns of field ``name`` in ``flat`` (for code that holds (n, words) arrays)."""
        w = self._word_of[name]
        return slice(w, w + self.field(name).comps)

    # -- GLSL -------------------------------------------------------------------------------
    def _decode(self, f: Field, raw: str) -> str:
        """GLSL expression of field ``f`` from its raw storage expression ``raw``."""
        if f.stored_as == "value":
            return f"uint({raw} + 0.5)"
        if f.base == self.word:
            return raw
        return f"{_BITS[(self.word, f.base)]}({raw})"

    def _read(self, f: Field, slot_expr) -> str:
        """Decoded GLSL expression of ``f``; ``slot_expr(k)`` is the expression of slot k."""
        w = self._word_of[f.name]
        if self.slot_words > 1:
            return self._decode(f, self._raw(f, slot_expr(w // self.slot_words), True))
        words = [self._decode(f, slot_expr(w + c)) for c in range(f.comps)]
        return words[0] if f.comps == 1 else f"{f.type}({', '.join(words)})"

    def _encode(self, f: Field, value: str) -> str:
        if f.stored_as == "value":
            return f"float({value})"
        if f.base == self.word:
            return value
        return f"{_BITS[(f.base, self.word)]}({value})"

    def _raw(self, f: Field, slot_expr: str, slot_vector: bool) -> str:
        """Raw read of ``f`` from the expression of its slot."""
        if not slot_vector:                       # slot_words == 1: one word per slot
            return slot_expr
        c = self._word_of[f.name] % self.slot_words
        if c == 0 and f.comps == self.slot_words:
            return slot_expr
        return f"{slot_expr}.{_SWIZZLE[c:c + f.comps]}"

    def slot_type(self) -> str:
        return glsl_vector(self.word, self.slot_words)

    def glsl_comment(self, indent: str = "//   ") -> str:
        """One line per field: words, type, name and what it holds."""
        lines = []
        for f in self.fields:
            w = self._word_of[f.name]
            span = f"{w}" if f.comps == 1 else f"{w}-{w + f.comps - 1}"
            how = " (a float value)" if f.stored_as == "value" else ""
            lines.append(f"{indent}word {span:<5} {f.type:<5} {f.name}: {f.doc}{how}")
        return "\n".join(lines)

    def glsl_getters(self, prefix: str, slot_expr) -> str:
        """``TYPE {prefix}{field}(uint i)`` per field; ``slot_expr(k)`` is the GLSL expression of
        slot k of record i (e.g. ``lambda k: f"receivers[4u * i + {k}u]"``)."""
        out = []
        for f in self.fields:
            out.append(f"{f.type} {prefix}{f.name}(uint i) {{ return {self._read(f, slot_expr)}; }}"
                       f"{'  // ' + f.doc if f.doc else ''}")
        return "\n".join(out)

    def glsl_struct(self, struct: str | None = None) -> str:
        struct = struct or self.name
        width = max(len(f"{f.type} {f.name};") for f in self.fields)
        body = "\n".join(f"    {f'{f.type} {f.name};':<{width}}  // {f.doc}" for f in self.fields)
        return f"struct {struct} {{\n{body}\n}};"

    def std430_struct_ok(self) -> bool:
        """True when the GLSL struct, as an std430 array element, has exactly this layout: every
        field a 32-bit scalar, no padding (vectors would be aligned to 8 or 16 bytes)."""
        return (all(f.comps == 1 and f.stored_as is None for f in self.fields)
                and sum(f.comps for f in self.fields) == self.words)

    def glsl_unpack(self, fn: str, struct: str | None = None) -> str:
        """``Struct fn(slot s0, slot s1, ...)``: the struct from the record's slot vectors."""
        struct = struct or self.name
        st = self.slot_type()
        args = ", ".join(f"{st} s{k}" for k in range(self.slots))
        vals = ", ".join(self._read(f, lambda k: f"s{k}") for f in self.fields)
        return f"{struct} {fn}({args}) {{ return {struct}({vals}); }}"

    def glsl_pack(self, fn: str, struct: str | None = None) -> str:
        """The inverse of ``glsl_unpack``: one slot -> ``slot fn(Struct v)``; several ->
        ``void fn(Struct v, out slot s0, ...)``. Padding words are 0."""
        struct = struct or self.name
        st = self.slot_type()
        zero = "0.0" if self.word == "float" else "0u"
        slots = []
        for k in range(self.slots):
            comps = []
            for w in range(k * self.slot_words, (k + 1) * self.slot_words):
                f = next((f for f in self.fields if self._word_of[f.name] <= w
                          < self._word_of[f.name] + f.comps), None)
                if f is None:
                    comps.append(zero)
                elif self.slot_words == 1 and f.comps > 1:       # a vector over scalar slots
                    c = w - self._word_of[f.name]
                    comps.append(self._encode(f, f"v.{f.name}.{_SWIZZLE[c]}"))
                elif self._word_of[f.name] == w:
                    comps.append(self._encode(f, f"v.{f.name}"))
            slots.append(f"{st}({', '.join(comps)})")
        if self.slots == 1:
            return f"{st} {fn}({struct} v) {{ return {slots[0]}; }}"
        outs = "".join(f", out {st} s{k}" for k in range(self.slots))
        body = " ".join(f"s{k} = {s};" for k, s in enumerate(slots))
        return f"void {fn}({struct} v{outs}) {{ {body} }}"

    def glsl_word_defines(self, prefix: str) -> str:
        """``#define {prefix}{FIELD} word`` per field: indexes into a word array."""
        return "\n".join(f"#define {prefix}{f.name.upper()} {self._word_of[f.name]}"
                         f"{'  // ' + f.doc if f.doc else ''}" for f in self.fields)

    # -- vertex buffers -------------------------------------------------------------------------
    def vertex_format(self) -> str:
        """moderngl's buffer format of the record as one vertex ("3f 3f 2f 4f"); fields are
        tightly packed (slot_words 1)."""
        if self.slot_words != 1 or sum(f.comps for f in self.fields) != self.words:
            raise ValueError(f"{self.name}: a vertex record is tightly packed (slot_words=1)")
        return " ".join(f"{f.comps}{_MODERNGL[f.base]}" for f in self.fields)

    def field_array(self, name: str, values) -> np.ndarray:
        """``values`` as the contiguous (n, comps) array a buffer of field ``name`` alone holds
        (a vertex record kept one buffer per field, e.g. so one field can be rewritten alone)."""
        f = self.field(name)
        a = np.ascontiguousarray(values, dtype=_NUMPY[f.base])
        ok = a.shape[1] == f.comps if a.ndim == 2 else (a.ndim == 1 and f.comps == 1)
        if not ok:
            raise ValueError(f"{self.name}.{name}: expected (n, {f.comps}) values, got {a.shape}")
        return a

    def vertex_content(self, buffers: dict, prefix: str = "in_") -> list[tuple]:
        """moderngl ``vertex_array`` content for a vertex record kept one buffer per field:
        ``(buffer, "3f", "in_position")`` per field, in declaration (= location) order."""
        if set(buffers) != {f.name for f in self.fields}:
            raise ValueError(f"{self.name}: one buffer per field {[f.name for f in self.fields]}, "
                             f"got {sorted(buffers)}")
        return [(buffers[f.name], f"{f.comps}{_MODERNGL[f.base]}", f"{prefix}{f.name}")
                for f in self.fields]

    def glsl_vertex_inputs(self, prefix: str = "in_") -> str:
        """``layout(location = k) in TYPE {prefix}{field};`` per field, in order."""
        return "\n".join(f"layout(location = {k}) in {f.type} {prefix}{f.name};"
                         f"{'  // ' + f.doc if f.doc else ''}" for k, f in enumerate(self.fields))

    # -- textures / images --------------------------------------------------------------------
    @property
    def texel_components(self) -> int:
        """Components of the texture a one-slot record is a texel of (its used words)."""
        if self.slots != 1:
            raise ValueError(f"{self.name} is not a one-texel record")
        return self.words

    @property
    def texture_dtype(self) -> str:
        """moderngl dtype of that texture."""
        return "f4" if self.word == "float" else "u4"

    @property
    def image_format(self) -> str:
        """GLSL image format qualifier of that texture: r32ui, rg32ui, rgba32f, ..."""
        comps = ("r", "rg", "rgb", "rgba")[self.texel_components - 1]
        return f"{comps}32{'f' if self.word == 'float' else 'ui'}"


class Units:
    """Named binding points of one kind (SSBO bindings, texture units, image units), declared
    once for ``bind_to_storage_buffer`` / ``use(location=...)`` / ``bind_to_image`` in Python
    and generated into GLSL as ``#define {prefix}{NAME} n`` for ``layout(binding = ...)``.
    Several names may share a number when no program uses both (``users`` says who does)."""

    def __init__(self, kind: str, prefix: str, table: dict[str, tuple[int, str]]):
        self.kind, self.prefix = kind, prefix
        self._table = {k: (int(v), doc) for k, (v, doc) in table.items()}
        for k, (v, _) in self._table.items():
            setattr(self, k, v)

    def items(self):
        return ((k, v) for k, (v, _) in self._table.items())

    def define(self, name: str) -> str:
        return f"{self.prefix}{name}"

    def glsl(self) -> str:
        lines = [f"// {self.kind}"]
        width = max(len(self.define(k)) for k in self._table)
        for k, (v, doc) in self._table.items():
            lines.append(f"#define {self.define(k):<{width}} {v}  // {doc}")
        return "\n".join(lines)
