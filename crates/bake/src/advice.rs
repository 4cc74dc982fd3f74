//! What a file does that a bake would misread, said once each before the work: warnings
//! from the scene and the lights' first pass alone (no form factor or link needed).
//!
//! Not errors: each of these bakes, and may be what the author meant.

use scene::{LightKind, Scene};

/// A point or spot light that puts less than this share of its flux on any surface facing
/// it is probably inside or behind geometry (a bulb inside a closed lampshade, a light under
/// the floor). A light above an open floor still puts ~20–50 % there.
pub const LIGHT_REACH_WARNING: f64 = 0.01;

/// Materials whose emissive texture is their base-colour picture: web assets use it as a
/// display trick (the surface looks lit without lights), and a bake would turn every such
/// surface into a lamp.
pub fn emissive_is_base_colour(scene: &Scene) -> Option<String> {
    let mut used = vec![false; scene.materials.len()];
    for p in &scene.polygons {
        if let Some(u) = used.get_mut(p.material) {
            *u = true;
        }
    }
    let image = |reference: &Option<scene::TextureRef>| {
        reference
            .as_ref()
            .and_then(|r| scene.textures.get(r.texture))
            .map(|t| t.image)
    };
    let named: Vec<String> = scene
        .materials
        .iter()
        .enumerate()
        .filter(|(k, m)| {
            used[*k]
                && m.emission.iter().any(|&e| e > 0.0)
                && image(&m.emissive_texture).is_some()
                && image(&m.emissive_texture) == image(&m.base_color_texture)
        })
        .map(|(k, m)| material_name(m.name.as_deref(), k))
        .collect();
    if named.is_empty() {
        return None;
    }
    Some(format!(
        "{} use{} the base-colour texture as the emissive texture (a display trick of web \
         assets): every texel emits, so these surfaces light the scene as lamps; remove \
         emissiveTexture or set emissiveFactor to 0 if they are not lights",
        list(&named),
        if named.len() == 1 { "s" } else { "" }
    ))
}

/// Point and spot lights that put less than [`LIGHT_REACH_WARNING`] of their flux on any
/// surface facing them (`stats` per light, as `direct::illuminate` gave them).
pub fn lights_reaching_little(scene: &Scene, stats: &[direct::LightStats]) -> Vec<String> {
    scene
        .lights
        .iter()
        .zip(stats)
        .enumerate()
        .filter_map(|(k, (light, s))| {
            // `flux` is Σ A_i E_i / I: the solid angle (sr) the lit surfaces subtend, cosine
            // weighted by the source's distribution; a point light's whole sphere is 4π, a
            // spot's cone 2π(1 − cos outer).
            let whole = match light.kind {
                LightKind::Point => 4.0 * std::f64::consts::PI,
                LightKind::Spot { outer, .. } => 2.0 * std::f64::consts::PI * (1.0 - outer.cos()),
                LightKind::Directional => return None,
            };
            if light.intensity <= 0.0 || whole <= 0.0 {
                return None;
            }
            let share = s.flux / whole;
            (share < LIGHT_REACH_WARNING).then(|| {
                let name = match light.name.as_deref() {
                    Some(name) => format!("{} light {name:?} ({k})", light.kind.name()),
                    None => format!("{} light {k}", light.kind.name()),
                };
                let node = scene
                    .layout
                    .nodes
                    .get(light.node)
                    .and_then(|n| n.name.as_deref());
                let node = match node {
                    Some(n) => format!("node {n:?} ({})", light.node),
                    None => format!("node {}", light.node),
                };
                format!(
                    "{name} on {node} puts {:.2}% of its light on any surface facing it \
                     ({} elements lit): it may sit inside or behind geometry (a closed \
                     lampshade, under a floor); move it or check the surfaces' facing",
                    100.0 * share,
                    s.elements_lit
                )
            })
        })
        .collect()
}

/// The warning for a scene with nothing that gives light.
pub fn no_light() -> String {
    "the scene has no emitters and no lights: every radiosity is 0; add a light \
     (KHR_lights_punctual point, spot or sun), an emissive material (emissiveFactor, MTL Ke) \
     or a sky (--sky uniform:L or overcast:Lz)"
        .to_string()
}

/// `material "name" (k)`, or `material k` when unnamed: how warnings name a material.
pub(crate) fn material_name(name: Option<&str>, k: usize) -> String {
    match name {
        Some(name) => format!("material {name:?} ({k})"),
        None => format!("material {k}"),
    }
}

/// Up to eight names joined, and how many more.
pub(crate) fn list(names: &[String]) -> String {
    const SHOWN: usize = 8;
    let shown = names[..names.len().min(SHOWN)].join(", ");
    if names.len() > SHOWN {
        format!("{shown} and {} more", names.len() - SHOWN)
    } else {
        shown
    }
}
