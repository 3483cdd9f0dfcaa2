// The terrain's material: Lambert under the view's first directional light, plus ambient.
// Bevy's PBR fragment costs ~0.8 µs per pixel on a software rasteriser; this costs a few ns
// and lights the ground the way the forest pass lights the trees.

#import bevy_pbr::forward_io::VertexOutput
#import bevy_pbr::mesh_view_bindings::lights

struct TerrainMaterial {
    ambient: vec4<f32>,
    diffuse: vec4<f32>,
}

@group(#{MATERIAL_BIND_GROUP}) @binding(0) var<uniform> material: TerrainMaterial;

@fragment
fn fragment(in: VertexOutput) -> @location(0) vec4<f32> {
    var lit = material.ambient.rgb;
    if lights.n_directional_lights > 0u {
        let sun = lights.directional_lights[0];
        // The light's colour arrives multiplied by its illuminance: keep the hue only, as
        // the forest pass does.
        let color = sun.color.rgb / max(max(sun.color.r, sun.color.g), max(sun.color.b, 1e-6));
        let diffuse = max(dot(normalize(in.world_normal), sun.direction_to_light), 0.0);
        lit += color * material.diffuse.rgb * diffuse;
    }
    return vec4<f32>(lit, 1.0);
}
