//! The layers a view composites and an export carries, bottom up: the result (the mesh's
//! texture or colours, a transfer's result, an application's outcome), the paint and a mask,
//! each with a visibility and an opacity. A hidden result shows the neutral grey of an
//! uncoloured mesh. Visibility and opacity change what is shown and exported, never what the
//! applications read (completion reads the paint, exemplar painting's region the mask).

use super::*;

/// How one layer is shown.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LayerShow {
    /// Shown (and exported) at all.
    pub visible: bool,
    /// 0 (transparent) ..= 1 (as painted).
    pub opacity: f32,
}

impl Default for LayerShow {
    fn default() -> Self {
        LayerShow {
            visible: true,
            opacity: 1.0,
        }
    }
}

impl LayerShow {
    /// The weight the layer is composited with: its opacity when visible, else 0.
    pub fn weight(&self) -> f32 {
        if self.visible {
            self.opacity.clamp(0.0, 1.0)
        } else {
            0.0
        }
    }
}

/// Which layer the brush and the fills paint into.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PaintTarget {
    /// The paint layer.
    #[default]
    Paint,
    /// The mask layer (exemplar painting's region when it has any).
    Mask,
}

/// Visibility and opacity of the result, the paint and the mask.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Layers {
    /// The mesh's own signal or a result.
    pub result: LayerShow,
    /// The brush's paint.
    pub paint: LayerShow,
    /// The mask.
    pub mask: LayerShow,
}

impl Layers {
    /// Weights of the result, the paint and the mask.
    pub fn weights(&self) -> [f32; 3] {
        [
            self.result.weight(),
            self.paint.weight(),
            self.mask.weight(),
        ]
    }
}

/// Colour (sRGB) a hidden result shows: the grey of a mesh without colours.
pub const HIDDEN_RESULT: [f32; 3] = crate::render::gpu::DEFAULT_VERTEX_COLOR;

/// `top` (colour, coverage) over `under` with weight `w`.
#[inline]
pub fn over(under: [f32; 3], top: [f32; 4], w: f32) -> [f32; 3] {
    let a = (top[3] * w).clamp(0.0, 1.0);
    [0, 1, 2].map(|k| under[k] * (1.0 - a) + top[k] * a)
}

/// The result at weight `w` over the hidden-result grey.
#[inline]
pub fn result_shown(result: [f32; 3], w: f32) -> [f32; 3] {
    over(HIDDEN_RESULT, [result[0], result[1], result[2], 1.0], w)
}

impl<P: AppParams> AppState<P> {
    /// Show or change a layer: views redraw, vertex colours are rebuilt.
    pub fn set_layers(&mut self, layers: Layers) {
        if layers == self.layers {
            return;
        }
        self.layers = layers;
        for slot in self.meshes.iter_mut().flatten() {
            slot.colors_dirty = true;
        }
    }
}
