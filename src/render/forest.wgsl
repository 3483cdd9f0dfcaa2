// The forest pass: every primitive kind is one instanced draw whose instances are chunks
// (see `draw.rs`). Vertices are pulled from storage buffers; nothing comes from vertex
// buffers.

#import bevy_render::view::View

const NO_RING: u32 = 0xffffffffu;
const TRIANGLES_PER_CHUNK: u32 = 32u;
const LINES_PER_CHUNK: u32 = 16u;
const POINTS_PER_CHUNK: u32 = 32u;
const PART_LEAVES: u32 = 1u;

struct Light {
    // Unit vector towards the light, w unused.
    direction: vec4<f32>,
    // Linear colour, w unused.
    color: vec4<f32>,
}

struct Vertex {
    position: vec3<f32>,
    ring: u32,
    normal: vec3<f32>,
    pad: u32,
}

struct Primitive {
    a: vec3<f32>,
    ring_a: u32,
    b: vec3<f32>,
    ring_b: u32,
}

struct Shading {
    // rgb ambient, w shininess.
    ambient_shininess: vec4<f32>,
    diffuse: vec4<f32>,
    specular: vec4<f32>,
}

struct Instance {
    row0: vec4<f32>,
    row1: vec4<f32>,
    row2: vec4<f32>,
    trunk: Shading,
    leaves: Shading,
    ring_base: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

struct Chunk {
    instance: u32,
    first: u32,
    count: u32,
    param: u32,
}

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<uniform> light: Light;

@group(1) @binding(0) var<storage, read> vertices: array<Vertex>;
@group(1) @binding(1) var<storage, read> indices: array<u32>;
@group(1) @binding(2) var<storage, read> primitives: array<Primitive>;

@group(2) @binding(0) var<storage, read> instances: array<Instance>;
@group(2) @binding(1) var<storage, read> chunks: array<Chunk>;
@group(2) @binding(2) var<storage, read> ring_offsets: array<vec4<f32>>;
// (instance, primitive) of each slot of the gathered chunks.
@group(2) @binding(3) var<storage, read> gathered: array<vec2<u32>>;

// `Chunk::instance` of a chunk whose slots are listed in `gathered` from `first` on.
const GATHERED: u32 = 0xffffffffu;

struct Slot {
    instance: u32,
    primitive: u32,
}

// The instance and primitive in slot `slot` of `chunk` (see `FrameChunks` in draw.rs).
fn chunk_slot(chunk: Chunk, slot: u32) -> Slot {
    if chunk.instance == GATHERED {
        let entry = gathered[chunk.first + slot];
        return Slot(entry.x, entry.y);
    }
    return Slot(chunk.instance, chunk.first + slot);
}

struct LitVertex {
    @builtin(position) clip: vec4<f32>,
    @location(0) world_normal: vec3<f32>,
    @location(1) world_position: vec3<f32>,
    @location(2) @interpolate(flat) instance: u32,
    @location(3) @interpolate(flat) part: u32,
}

struct FlatVertex {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) color: vec4<f32>,
}

// Circumradius of an octagon of the same area as a `size`-pixel square, over `size`
// (`2√2 r² = 1`), so that the static LOD's coverage (`area / size²` points) holds for round
// points too.
const OCTAGON_PER_SQUARE: f32 = 0.5946036;

// Corner `corner` (0..8) of a round point's octagon on the unit circle (`batch.rs` fans
// the eight corners): round without a `discard`, which would turn off the early depth
// test. The corners sit off the axes, at 22.5° + k·45°.
fn octagon_corner(corner: u32) -> vec2<f32> {
    let c = 0.9238795;
    let s = 0.3826834;
    var corners = array<vec2<f32>, 8>(
        vec2<f32>(c, s), vec2<f32>(s, c), vec2<f32>(-s, c), vec2<f32>(-c, s),
        vec2<f32>(-c, -s), vec2<f32>(-s, -c), vec2<f32>(s, -c), vec2<f32>(c, -s),
    );
    return corners[corner];
}

// Outside the clip volume on every axis: a triangle made of it covers nothing.
const DEGENERATE: vec4<f32> = vec4<f32>(2.0, 2.0, 2.0, 1.0);

fn ring_offset(instance: Instance, ring: u32) -> vec3<f32> {
    if instance.ring_base == NO_RING || ring == NO_RING {
        return vec3<f32>(0.0);
    }
    return ring_offsets[instance.ring_base + ring].xyz;
}

fn to_world(instance: Instance, p: vec3<f32>) -> vec3<f32> {
    let h = vec4<f32>(p, 1.0);
    return vec3<f32>(dot(instance.row0, h), dot(instance.row1, h), dot(instance.row2, h));
}

// Rotation and uniform scale only (tree instances carry no shear), so the normal goes
// through the same 3×3 and is renormalised.
fn normal_to_world(instance: Instance, n: vec3<f32>) -> vec3<f32> {
    let h = vec4<f32>(n, 0.0);
    return normalize(vec3<f32>(dot(instance.row0, h), dot(instance.row1, h), dot(instance.row2, h)));
}

fn blinn_phong(shading: Shading, normal: vec3<f32>, to_eye: vec3<f32>) -> vec3<f32> {
    let l = light.direction.xyz;
    let diffuse = max(dot(normal, l), 0.0);
    let h = normalize(l + to_eye);
    var specular = 0.0;
    if diffuse > 0.0 {
        specular = pow(max(dot(normal, h), 0.0), max(shading.ambient_shininess.w, 1.0));
    }
    return shading.ambient_shininess.rgb
        + light.color.rgb * (shading.diffuse.rgb * diffuse + shading.specular.rgb * specular);
}

fn eye_direction(world_position: vec3<f32>) -> vec3<f32> {
    // An orthographic view looks along its -Z axis everywhere.
    if view.clip_from_view[3][3] == 1.0 {
        return normalize(view.world_from_view[2].xyz);
    }
    return normalize(view.world_position - world_position);
}

@vertex
fn vs_triangles(@builtin(vertex_index) vertex: u32, @builtin(instance_index) chunk_index: u32) -> LitVertex {
    var out: LitVertex;
    let chunk = chunks[chunk_index];
    let triangle = vertex / 3u;
    if triangle >= chunk.count {
        out.clip = DEGENERATE;
        return out;
    }
    let slot = chunk_slot(chunk, triangle);
    let instance = instances[slot.instance];
    let v = vertices[indices[slot.primitive * 3u + vertex % 3u]];
    let world = to_world(instance, v.position + ring_offset(instance, v.ring));
    out.clip = view.clip_from_world * vec4<f32>(world, 1.0);
    out.world_position = world;
    out.world_normal = normal_to_world(instance, v.normal);
    out.instance = slot.instance;
    out.part = chunk.param;
    return out;
}

@fragment
fn fs_lit(in: LitVertex, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let instance = instances[in.instance];
    var shading = instance.trunk;
    if in.part == PART_LEAVES {
        shading = instance.leaves;
    }
    var normal = normalize(in.world_normal);
    if !front {
        normal = -normal;
    }
    return vec4<f32>(blinn_phong(shading, normal, eye_direction(in.world_position)), 1.0);
}

// Corner `corner` (0..4) of a quad, (end or x, side or y) in {0,1}², counter-clockwise:
// `CORNER_INDICES` (batch.rs) makes its two triangles of them.
fn quad_corner(corner: u32) -> vec2<f32> {
    return vec2<f32>(select(0.0, 1.0, corner == 1u || corner == 2u), select(0.0, 1.0, corner >= 2u));
}

fn viewport_size() -> vec2<f32> {
    return view.viewport.zw;
}

@vertex
fn vs_lines(@builtin(vertex_index) vertex: u32, @builtin(instance_index) chunk_index: u32) -> FlatVertex {
    var out: FlatVertex;
    let chunk = chunks[chunk_index];
    let line = vertex / 4u;
    if line >= chunk.count {
        out.clip = DEGENERATE;
        return out;
    }
    let slot = chunk_slot(chunk, line);
    let instance = instances[slot.instance];
    let p = primitives[slot.primitive];
    let world_a = to_world(instance, p.a + ring_offset(instance, p.ring_a));
    let world_b = to_world(instance, p.b + ring_offset(instance, p.ring_b));
    var a = view.clip_from_world * vec4<f32>(world_a, 1.0);
    var b = view.clip_from_world * vec4<f32>(world_b, 1.0);
    // Reverse-Z: a point is in front of the near plane when z <= w. Clip the segment there
    // so that an end behind the camera does not flip the quad.
    let da = a.w - a.z;
    let db = b.w - b.z;
    if da < 0.0 && db < 0.0 {
        out.clip = DEGENERATE;
        return out;
    }
    if da < 0.0 {
        a = mix(a, b, da / (da - db));
    } else if db < 0.0 {
        b = mix(b, a, db / (db - da));
    }
    let size = viewport_size();
    let screen_a = a.xy / a.w * size * 0.5;
    let screen_b = b.xy / b.w * size * 0.5;
    var along = screen_b - screen_a;
    if dot(along, along) < 1e-12 {
        along = vec2<f32>(1.0, 0.0);
    }
    along = normalize(along);
    let corner = quad_corner(vertex % 4u);
    let across = vec2<f32>(-along.y, along.x) * f32(chunk.param) * (corner.y - 0.5);
    var end = a;
    if corner.x > 0.5 {
        end = b;
    }
    let offset_ndc = across * 2.0 / size;
    out.clip = vec4<f32>(end.xy + offset_ndc * end.w, end.z, end.w);
    // Lit as the trunk's cylinder is where it faces the eye: the normal across the segment
    // towards the eye, so a line keeps the colour of the triangles it replaces.
    let to_eye = eye_direction(0.5 * (world_a + world_b));
    let axis = world_b - world_a;
    var normal = to_eye;
    if dot(axis, axis) > 1e-12 {
        let unit = normalize(axis);
        let across_eye = to_eye - unit * dot(to_eye, unit);
        if dot(across_eye, across_eye) > 1e-12 {
            normal = normalize(across_eye);
        }
    }
    out.color = vec4<f32>(blinn_phong(instance.trunk, normal, to_eye), 1.0);
    return out;
}

// Point `point` of the chunk, its corner `offset` pixels from its centre.
fn point_vertex(chunk: Chunk, point: u32, offset: vec2<f32>) -> FlatVertex {
    var out: FlatVertex;
    if point >= chunk.count {
        out.clip = DEGENERATE;
        return out;
    }
    let slot = chunk_slot(chunk, point);
    let instance = instances[slot.instance];
    let p = primitives[slot.primitive];
    let world = to_world(instance, p.a + ring_offset(instance, p.ring_a));
    let center = view.clip_from_world * vec4<f32>(world, 1.0);
    if center.w - center.z < 0.0 {
        out.clip = DEGENERATE;
        return out;
    }
    let offset_ndc = offset * 2.0 / viewport_size();
    out.clip = vec4<f32>(center.xy + offset_ndc * center.w, center.z, center.w);
    // Leaves are two-sided: light the side facing the eye.
    let to_eye = eye_direction(world);
    var normal = normal_to_world(instance, p.b);
    if dot(normal, to_eye) < 0.0 {
        normal = -normal;
    }
    out.color = vec4<f32>(blinn_phong(instance.leaves, normal, to_eye), 1.0);
    return out;
}

@vertex
fn vs_square_points(@builtin(vertex_index) vertex: u32, @builtin(instance_index) chunk_index: u32) -> FlatVertex {
    let chunk = chunks[chunk_index];
    let offset = (quad_corner(vertex % 4u) - vec2<f32>(0.5)) * f32(chunk.param);
    return point_vertex(chunk, vertex / 4u, offset);
}

@vertex
fn vs_round_points(@builtin(vertex_index) vertex: u32, @builtin(instance_index) chunk_index: u32) -> FlatVertex {
    let chunk = chunks[chunk_index];
    let offset = octagon_corner(vertex % 8u) * (f32(chunk.param) * OCTAGON_PER_SQUARE);
    return point_vertex(chunk, vertex / 8u, offset);
}

@fragment
fn fs_flat(in: FlatVertex) -> @location(0) vec4<f32> {
    return in.color;
}
