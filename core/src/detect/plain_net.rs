//! The detector's folded networks run by plain loops, for inference. Both networks are chains of
//! 3 × 3 convolutions in burn's groups (the stem, the depthwise layers, stage 2's full class and
//! offset heads) and 1 × 1 convolutions (the pointwise layers, the other heads), each followed
//! by a bias and mostly a ReLU. burn's CPU backend runs each of those as its own pass over the activation —
//! convolution into a zeroed buffer, bias, ReLU — and its depthwise kernel was 40 % of the
//! stage-1 network's samples on the 640×480 speed set; here each layer is one pass that keeps
//! its rows or pixel tiles in the L1 cache and adds the bias and ReLU on the way out
//! (docs/BENCHMARKS-HISTORY.md: "the networks by plain loops"). Training keeps burn's layers; a
//! [`PlainNet`] is built from them once their batch norms are folded, and computes the same
//! function up to the order of the float additions.

use burn::nn::conv::Conv2d;
use burn::nn::PaddingConfig2d;

/// Floats of a thread's buffers kept between forward passes (64 MB): the activations of a
/// 1280×960 image's levels fit, so a stream of images allocates and zeroes nothing; a larger
/// image's are freed after it.
const KEPT_WORKSPACE: usize = 16 << 20;

thread_local! {
    /// The two activations a layer reads and writes, and the padded input planes.
    static WORKSPACE: std::cell::RefCell<[Vec<f32>; 3]> = const {
        std::cell::RefCell::new([Vec::new(), Vec::new(), Vec::new()])
    };
}

/// A chain of layers on one image's planes (C × H × W, row-major).
#[derive(Debug, Clone)]
pub struct PlainNet {
    layers: Vec<Layer>,
}

#[derive(Debug, Clone)]
enum Layer {
    Spatial(Spatial),
    Pointwise(Pointwise),
}

/// 3 × 3, zero padding of one dilation, in groups as burn's: each output channel reads the input
/// channels of its group (a depthwise layer its own; the stem's one input feeds all; a head's
/// every input feeds every output).
#[derive(Debug, Clone)]
struct Spatial {
    inputs: usize,
    outputs: usize,
    groups: usize,
    stride: usize,
    dilation: usize,
    /// `outputs` × inputs per group × 9, row by row (burn's layout).
    weights: Vec<f32>,
    bias: Vec<f32>,
    relu: bool,
}

/// 1 × 1 over all input channels.
#[derive(Debug, Clone)]
struct Pointwise {
    inputs: usize,
    outputs: usize,
    /// `inputs` × `outputs` (transposed from burn's), so that a block of output channels finds
    /// its weights for one input side by side.
    weights: Vec<f32>,
    bias: Vec<f32>,
    relu: bool,
}

/// Why a burn convolution has no plain counterpart.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("layer {layer}: {what}")]
pub struct Unsupported {
    pub layer: usize,
    pub what: String,
}

impl PlainNet {
    /// The chain of `convs` (each with whether a ReLU follows it). Every convolution must be a
    /// 3 × 3 one padded by its dilation (any groups, equal strides and dilations along both
    /// axes) or an unpadded 1 × 1 one over all channels with stride 1.
    pub fn from_convs(convs: &[(&Conv2d, bool)]) -> Result<Self, Unsupported> {
        let layers = convs
            .iter()
            .enumerate()
            .map(|(i, &(conv, relu))| {
                Layer::of(conv, relu).map_err(|what| Unsupported { layer: i, what })
            })
            .collect::<Result<Vec<_>, _>>()?;
        for (i, pair) in layers.windows(2).enumerate() {
            if pair[0].outputs() != pair[1].inputs() {
                return Err(Unsupported {
                    layer: i + 1,
                    what: format!(
                        "{} input channels after {} output channels",
                        pair[1].inputs(),
                        pair[0].outputs()
                    ),
                });
            }
        }
        Ok(Self { layers })
    }

    pub fn input_channels(&self) -> usize {
        self.layers.first().map_or(0, Layer::inputs)
    }

    pub fn output_channels(&self) -> usize {
        self.layers.last().map_or(0, Layer::outputs)
    }

    /// The output's height and width for an input of `height` × `width`.
    pub fn output_size(&self, height: usize, width: usize) -> (usize, usize) {
        (self.layers.iter()).fold((height, width), |(h, w), layer| layer.output_size(h, w))
    }

    /// `input`: N images of [`Self::input_channels`] × `height` × `width` → N ×
    /// [`Self::output_channels`] × [`Self::output_size`].
    pub fn forward(&self, input: &[f32], n: usize, height: usize, width: usize) -> Vec<f32> {
        let per_image = self.input_channels() * height * width;
        assert_eq!(input.len(), n * per_image, "input of {n} images");
        let (oh, ow) = self.output_size(height, width);
        let mut out = Vec::with_capacity(n * self.output_channels() * oh * ow);
        // Two buffers, each as large as the largest activation, that the layers write in turn.
        let mut largest = per_image;
        let (mut h, mut w) = (height, width);
        for layer in &self.layers {
            (h, w) = layer.output_size(h, w);
            largest = largest.max(layer.outputs() * h * w);
        }
        WORKSPACE.with_borrow_mut(|workspace| {
            for buffer in &mut workspace[..2] {
                if buffer.len() < largest {
                    buffer.resize(largest, 0.0);
                }
            }
            let size = (height, width);
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                // SAFETY: the CPU has both features the function is compiled for.
                unsafe { self.images_avx2(input, n, size, workspace, &mut out) };
            } else {
                self.images::<false, PORTABLE_LANES>(input, n, size, workspace, &mut out);
            }
            #[cfg(not(target_arch = "x86_64"))]
            self.images::<false, PORTABLE_LANES>(input, n, size, workspace, &mut out);
            // A huge image's buffers are not kept for the next one.
            for buffer in workspace.iter_mut() {
                if buffer.len() > KEPT_WORKSPACE {
                    *buffer = Vec::new();
                }
            }
        });
        out
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn images_avx2(
        &self,
        input: &[f32],
        n: usize,
        size: (usize, usize),
        workspace: &mut [Vec<f32>; 3],
        out: &mut Vec<f32>,
    ) {
        self.images::<true, AVX_LANES>(input, n, size, workspace, out)
    }

    /// The layers on each of `n` images into `out`. `FMA`: multiply-adds as fused instructions
    /// (only where the CPU has them: without, a fused multiply-add is a call into the maths
    /// library).
    #[inline(always)]
    fn images<const FMA: bool, const L: usize>(
        &self,
        input: &[f32],
        n: usize,
        (height, width): (usize, usize),
        [from, to, scratch]: &mut [Vec<f32>; 3],
        out: &mut Vec<f32>,
    ) {
        let per_image = self.input_channels() * height * width;
        for image in input.chunks_exact(per_image.max(1)).take(n) {
            from[..per_image].copy_from_slice(image);
            let (mut h, mut w) = (height, width);
            for layer in &self.layers {
                let (lh, lw) = layer.output_size(h, w);
                let (src, dst) = (
                    &from[..layer.inputs() * h * w],
                    &mut to[..layer.outputs() * lh * lw],
                );
                match layer {
                    Layer::Spatial(layer) => spatial::<FMA, L>(layer, src, h, w, dst, scratch),
                    Layer::Pointwise(layer) => pointwise::<FMA, L>(layer, src, h * w, dst),
                }
                std::mem::swap(from, to);
                (h, w) = (lh, lw);
            }
            out.extend_from_slice(&from[..self.output_channels() * h * w]);
        }
    }
}

impl Layer {
    fn of(conv: &Conv2d, relu: bool) -> Result<Self, String> {
        let weights = conv.weight.val();
        let [outputs, per_group, kh, kw] = weights.dims();
        let inputs = per_group * conv.groups;
        let weights: Vec<f32> = weights
            .into_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .map_err(|e| format!("weights: {e:?}"))?;
        let bias = match &conv.bias {
            Some(b) => b
                .val()
                .into_data()
                .convert::<f32>()
                .try_into_vec::<f32>()
                .map_err(|e| format!("bias: {e:?}"))?,
            None => vec![0.0; outputs],
        };
        match [kh, kw] {
            [3, 3] => {
                let [s, s2] = conv.stride;
                let [d, d2] = conv.dilation;
                if s != s2 || d != d2 || s == 0 || d == 0 {
                    return Err(format!(
                        "stride {:?}, dilation {:?}",
                        conv.stride, conv.dilation
                    ));
                }
                if conv.padding != PaddingConfig2d::Explicit(d, d, d, d) {
                    return Err(format!("padding {:?} (needs {d} all round)", conv.padding));
                }
                if conv.groups == 0 || !outputs.is_multiple_of(conv.groups) {
                    return Err(format!("{outputs} outputs in {} groups", conv.groups));
                }
                Ok(Layer::Spatial(Spatial {
                    inputs,
                    outputs,
                    groups: conv.groups,
                    stride: s,
                    dilation: d,
                    weights,
                    bias,
                    relu,
                }))
            }
            [1, 1] => {
                if conv.groups != 1 || conv.stride != [1, 1] {
                    return Err(format!(
                        "1 × 1 in {} groups, stride {:?}",
                        conv.groups, conv.stride
                    ));
                }
                if !matches!(
                    conv.padding,
                    PaddingConfig2d::Valid | PaddingConfig2d::Explicit(0, 0, 0, 0)
                ) {
                    return Err(format!("1 × 1 with padding {:?}", conv.padding));
                }
                let weights = (0..inputs * outputs)
                    .map(|k| weights[(k % outputs) * inputs + k / outputs])
                    .collect();
                Ok(Layer::Pointwise(Pointwise {
                    inputs,
                    outputs,
                    weights,
                    bias,
                    relu,
                }))
            }
            k => Err(format!("kernel {k:?}")),
        }
    }

    fn inputs(&self) -> usize {
        match self {
            Layer::Spatial(Spatial { inputs, .. }) | Layer::Pointwise(Pointwise { inputs, .. }) => {
                *inputs
            }
        }
    }

    fn output_size(&self, h: usize, w: usize) -> (usize, usize) {
        match self {
            Layer::Spatial(Spatial { stride, .. }) => (out_side(h, *stride), out_side(w, *stride)),
            Layer::Pointwise(_) => (h, w),
        }
    }

    fn outputs(&self) -> usize {
        match self {
            Layer::Spatial(Spatial { outputs, .. })
            | Layer::Pointwise(Pointwise { outputs, .. }) => *outputs,
        }
    }
}

/// A side after a 3 × 3 convolution padded by its dilation.
fn out_side(side: usize, stride: usize) -> usize {
    if side == 0 {
        0
    } else {
        (side - 1) / stride + 1
    }
}

#[inline(always)]
fn madd<const FMA: bool>(a: f32, b: f32, c: f32) -> f32 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// Output pixels per block of a row, summed over all taps before stored: two AVX registers.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
const AVX_LANES: usize = 16;
/// The same where vectors hold four floats (x86-64 without AVX2, WebAssembly's SIMD): two
/// vectors, so that a 3 × 3 layer's sums and its nine weights fit the sixteen registers, and a
/// 1 × 1 layer's [`OUTPUT_BLOCK`] channels of sums take eight. Sixteen pixels there spilled
/// the sums to memory at every tap (BENCHMARKS.md, "Studio, browser and CLI").
const PORTABLE_LANES: usize = 8;

/// A [`Spatial`] layer on `planes` (inputs × h × w) into `out` (outputs × oh × ow).
#[inline(always)]
fn spatial<const FMA: bool, const L: usize>(
    layer: &Spatial,
    planes: &[f32],
    h: usize,
    w: usize,
    out: &mut [f32],
    scratch: &mut Vec<f32>,
) {
    let Spatial {
        inputs,
        outputs,
        groups,
        stride,
        dilation,
        weights,
        bias,
        relu,
    } = layer;
    let (s, d) = (*stride, *dilation);
    let (oh, ow) = (out_side(h, s), out_side(w, s));
    let (group_inputs, group_outputs) = (inputs / groups, outputs / groups);
    // Each input plane of a group zero-padded by the dilation and its columns split by their
    // remainder modulo the stride (phase p holds padded columns p, p + s, …): every tap of an
    // output row is then one contiguous run of one phase's row.
    let (ph, pw) = (h + 2 * d, w + 2 * d);
    let len = pw.div_ceil(s);
    let padded = s * ph * len;
    if scratch.len() < group_inputs * padded {
        scratch.resize(group_inputs * padded, 0.0);
    }
    for g in 0..*groups {
        for ci in 0..group_inputs {
            let c = g * group_inputs + ci;
            let plane = &planes[c * h * w..(c + 1) * h * w];
            let phases = &mut scratch[ci * padded..(ci + 1) * padded];
            pad_into_phases(plane, h, w, s, d, phases);
        }
        let scratch = &scratch[..];
        for o in g * group_outputs..(g + 1) * group_outputs {
            for oy in 0..oh {
                let dst = &mut out[(o * oh + oy) * ow..(o * oh + oy + 1) * ow];
                // The row sums its group's inputs one after the other, in `dst` between them.
                for ci in 0..group_inputs {
                    let taps: [&[f32]; 9] = std::array::from_fn(|t| {
                        let (ky, kx) = (t / 3, t % 3);
                        let (py, col) = (oy * s + ky * d, kx * d);
                        let (p, j) = (col % s, col / s);
                        let start = ci * padded + (p * ph + py) * len + j;
                        &scratch[start..start + ow]
                    });
                    let at = (o * group_inputs + ci) * 9;
                    let k: &[f32; 9] = weights[at..at + 9].try_into().expect("9 taps");
                    let (first, last) = (ci == 0, ci + 1 == group_inputs);
                    let mut x = 0;
                    while x + L <= ow {
                        #[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
                        if L == wasm_simd::PIXELS {
                            let init = first.then_some(bias[o]);
                            wasm_simd::spatial_block(&taps, k, x, dst, init, *relu && last);
                            x += L;
                            continue;
                        }
                        let block = &mut dst[x..x + L];
                        let mut acc = [bias[o]; L];
                        if !first {
                            acc.copy_from_slice(block);
                        }
                        for (tap, &wt) in taps.iter().zip(k) {
                            let src: &[f32; L] = tap[x..x + L].try_into().expect("a block");
                            for (a, &v) in acc.iter_mut().zip(src) {
                                *a = madd::<FMA>(wt, v, *a);
                            }
                        }
                        store(block, &acc, *relu && last);
                        x += L;
                    }
                    for x in x..ow {
                        let mut acc = if first { bias[o] } else { dst[x] };
                        for (tap, &wt) in taps.iter().zip(k) {
                            acc = madd::<FMA>(wt, tap[x], acc);
                        }
                        dst[x] = if *relu && last { relu_of(acc) } else { acc };
                    }
                }
            }
        }
    }
}

/// `plane` (h × w) zero-padded by `d` all round into `phases` (s phases of (h + 2d) rows of
/// ⌈(w + 2d) / s⌉ columns; phase p holds the padded columns p, p + s, …).
#[inline(always)]
fn pad_into_phases(plane: &[f32], h: usize, w: usize, s: usize, d: usize, phases: &mut [f32]) {
    let (ph, len) = (h + 2 * d, (w + 2 * d).div_ceil(s));
    for p in 0..s {
        for py in 0..ph {
            let row = &mut phases[(p * ph + py) * len..(p * ph + py + 1) * len];
            if py < d || py >= d + h {
                row.fill(0.0);
                continue;
            }
            let src = &plane[(py - d) * w..(py - d + 1) * w];
            // Padded columns d..d + w hold the row; in phase p they are j = (d − p) / s
            // rounded up, every s-th column of the row from its (p + j s − d)-th.
            let first = (d.saturating_sub(p)).div_ceil(s);
            let skip = p + first * s - d;
            let count = if skip < w { (w - skip).div_ceil(s) } else { 0 };
            row[..first].fill(0.0);
            if s == 1 {
                row[first..first + count].copy_from_slice(&src[skip..skip + count]);
            } else {
                for (v, &x) in
                    (row[first..first + count].iter_mut()).zip(src[skip..].iter().step_by(s))
                {
                    *v = x;
                }
            }
            row[first + count..].fill(0.0);
        }
    }
}

/// max(x, 0) as a comparison and a select, not `f32::max`: WebAssembly's `f32.max` returns
/// NaN for a NaN argument where Rust's `max` returns the other, so the wasm build called libm's
/// `fmaxf` for every activation (16 % of the browser's detection) instead of vectorising. The
/// same values (a NaN becomes 0 either way; −0 becomes +0, which sums the same).
#[inline(always)]
fn relu_of(x: f32) -> f32 {
    if x > 0.0 {
        x
    } else {
        0.0
    }
}

#[inline(always)]
fn store(dst: &mut [f32], acc: &[f32], relu: bool) {
    if relu {
        for (d, &a) in dst.iter_mut().zip(acc) {
            *d = relu_of(a);
        }
    } else {
        dst.copy_from_slice(acc);
    }
}

/// Output channels summed together in [`pointwise`]: with [`AVX_LANES`] pixels each, eight
/// AVX registers of sums that every input load feeds four times.
const OUTPUT_BLOCK: usize = 4;

/// A [`Pointwise`] layer on `planes` (inputs × `pixels`) into `out` (outputs × `pixels`).
#[inline(always)]
fn pointwise<const FMA: bool, const L: usize>(
    layer: &Pointwise,
    planes: &[f32],
    pixels: usize,
    out: &mut [f32],
) {
    let Pointwise {
        inputs,
        outputs,
        weights,
        bias,
        relu,
    } = layer;
    let (inputs, outputs) = (*inputs, *outputs);
    let mut start = 0;
    while start + L <= pixels {
        let mut o = 0;
        while o + OUTPUT_BLOCK <= outputs {
            pointwise_block::<FMA, OUTPUT_BLOCK, L>(
                planes, pixels, start, o, outputs, weights, bias, *relu, out,
            );
            o += OUTPUT_BLOCK;
        }
        for o in o..outputs {
            pointwise_block::<FMA, 1, L>(
                planes, pixels, start, o, outputs, weights, bias, *relu, out,
            );
        }
        start += L;
    }
    for x in start..pixels {
        for o in 0..outputs {
            let mut acc = bias[o];
            for i in 0..inputs {
                acc = madd::<FMA>(weights[i * outputs + o], planes[i * pixels + x], acc);
            }
            out[o * pixels + x] = if *relu { relu_of(acc) } else { acc };
        }
    }
}

/// `OUTS` output channels from `first` on, pixels `start..start + L`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn pointwise_block<const FMA: bool, const OUTS: usize, const L: usize>(
    planes: &[f32],
    pixels: usize,
    start: usize,
    first: usize,
    outputs: usize,
    weights: &[f32],
    bias: &[f32],
    relu: bool,
    out: &mut [f32],
) {
    #[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
    if L == wasm_simd::PIXELS {
        return wasm_simd::pointwise_block::<OUTS>(
            planes, pixels, start, first, outputs, weights, bias, relu, out,
        );
    }
    let mut acc: [[f32; L]; OUTS] = std::array::from_fn(|j| [bias[first + j]; L]);
    for (plane, row) in planes
        .chunks_exact(pixels)
        .zip(weights.chunks_exact(outputs))
    {
        let src: &[f32; L] = plane[start..start + L].try_into().expect("a block");
        let wts: &[f32; OUTS] = row[first..first + OUTS].try_into().expect("a block");
        for (sums, &wt) in acc.iter_mut().zip(wts) {
            for (a, &v) in sums.iter_mut().zip(src) {
                *a = madd::<FMA>(wt, v, *a);
            }
        }
    }
    for (j, sums) in acc.iter().enumerate() {
        let o = first + j;
        store(
            &mut out[o * pixels + start..o * pixels + start + L],
            sums,
            relu,
        );
    }
}

/// The portable path's blocks written with WebAssembly's SIMD operations: the sums of a block of
/// [`PORTABLE_LANES`] pixels are two `v128` values the engine keeps in registers, each tap one
/// multiply and one add per vector, as the portable loops compute them (the same values).
#[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
mod wasm_simd {
    use core::arch::wasm32::{
        f32x4_add, f32x4_mul, f32x4_pmax, f32x4_splat, v128, v128_load, v128_store,
    };

    pub(super) const PIXELS: usize = super::PORTABLE_LANES;
    const _: () = assert!(PIXELS == 8, "two vectors of four floats");

    /// Eight floats from `at` as two vectors.
    #[inline(always)]
    fn load(from: &[f32], at: usize) -> [v128; 2] {
        let block = &from[at..at + PIXELS];
        let p = block.as_ptr();
        // SAFETY: `block` holds eight floats; v128 loads need no alignment.
        unsafe { [v128_load(p.cast()), v128_load(p.add(4).cast())] }
    }

    #[inline(always)]
    fn store(to: &mut [f32], at: usize, sums: [v128; 2], relu: bool) {
        let block = &mut to[at..at + PIXELS];
        let p = block.as_mut_ptr();
        let zero = f32x4_splat(0.0);
        // max(0, x) as `relu_of` has it: pmax(0, x) is x where 0 < x, else 0.
        let sums = if relu {
            sums.map(|v| f32x4_pmax(zero, v))
        } else {
            sums
        };
        // SAFETY: `block` holds eight floats; v128 stores need no alignment.
        unsafe {
            v128_store(p.cast(), sums[0]);
            v128_store(p.add(4).cast(), sums[1]);
        }
    }

    /// [`super::spatial`]'s block at `x`: from `init` (the bias) or from what `dst` holds.
    #[inline(always)]
    pub(super) fn spatial_block(
        taps: &[&[f32]; 9],
        k: &[f32; 9],
        x: usize,
        dst: &mut [f32],
        init: Option<f32>,
        relu: bool,
    ) {
        let mut acc = match init {
            Some(b) => [f32x4_splat(b); 2],
            None => load(dst, x),
        };
        for (tap, &wt) in taps.iter().zip(k) {
            let w = f32x4_splat(wt);
            let v = load(tap, x);
            acc = [
                f32x4_add(f32x4_mul(w, v[0]), acc[0]),
                f32x4_add(f32x4_mul(w, v[1]), acc[1]),
            ];
        }
        store(dst, x, acc, relu);
    }

    /// [`super::pointwise_block`] for eight pixels.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn pointwise_block<const OUTS: usize>(
        planes: &[f32],
        pixels: usize,
        start: usize,
        first: usize,
        outputs: usize,
        weights: &[f32],
        bias: &[f32],
        relu: bool,
        out: &mut [f32],
    ) {
        let mut acc: [[v128; 2]; OUTS] = std::array::from_fn(|j| [f32x4_splat(bias[first + j]); 2]);
        for (plane, row) in planes
            .chunks_exact(pixels)
            .zip(weights.chunks_exact(outputs))
        {
            let v = load(plane, start);
            for (sums, &wt) in acc.iter_mut().zip(&row[first..first + OUTS]) {
                let w = f32x4_splat(wt);
                *sums = [
                    f32x4_add(f32x4_mul(w, v[0]), sums[0]),
                    f32x4_add(f32x4_mul(w, v[1]), sums[1]),
                ];
            }
        }
        for (j, sums) in acc.into_iter().enumerate() {
            store(out, (first + j) * pixels + start, sums, relu);
        }
    }
}

/// The largest absolute difference between two maps of one length: how the tests hold the plain
/// loops (and the folded networks) to burn's layers.
#[cfg(test)]
pub(crate) fn largest_difference(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len(), "maps of different lengths");
    a.iter()
        .zip(b)
        .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::nn::conv::Conv2dConfig;
    use burn::tensor::activation::relu;
    use burn::tensor::{Device, Distribution, Tensor};

    fn burn_chain(convs: &[(&Conv2d, bool)], x: Tensor<4>) -> Tensor<4> {
        convs.iter().fold(x, |x, (conv, r)| {
            let y = conv.forward(x);
            if *r {
                relu(y)
            } else {
                y
            }
        })
    }

    fn random_bias(conv: &mut Conv2d, device: &Device) {
        let [outputs, ..] = conv.weight.val().dims();
        conv.bias = Some(burn::module::Param::from_tensor(Tensor::random(
            [outputs],
            Distribution::Normal(0.0, 0.5),
            device,
        )));
    }

    /// Odd sizes, both strides, dilations up to 4, the stem's one input to many outputs, groups
    /// of two, a 3 × 3 over all channels, heads without ReLU: the plain chain computes burn's.
    #[test]
    fn a_chain_of_every_layer_kind_computes_what_burn_does() {
        let device = Device::flex();
        let spatial = |cin: usize, cout: usize, s: usize, d: usize| {
            Conv2dConfig::new([cin, cout], [3, 3])
                .with_stride([s, s])
                .with_dilation([d, d])
                .with_padding(PaddingConfig2d::Explicit(d, d, d, d))
                .with_groups(cin)
                .init(&device)
        };
        let mut stem = spatial(1, 4, 2, 1);
        let mut dw1 = spatial(4, 4, 1, 1);
        let pw1 = Conv2dConfig::new([4, 8], [1, 1])
            .with_bias(false)
            .init(&device);
        let mut dw2 = spatial(8, 8, 2, 1);
        let mut dw3 = spatial(8, 8, 1, 4);
        let mut paired = Conv2dConfig::new([8, 4], [3, 3])
            .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
            .with_groups(2)
            .init(&device);
        let mut full = Conv2dConfig::new([4, 6], [3, 3])
            .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
            .init(&device);
        let mut head = Conv2dConfig::new([6, 3], [1, 1]).init(&device);
        for conv in [
            &mut stem,
            &mut dw1,
            &mut dw2,
            &mut dw3,
            &mut paired,
            &mut full,
            &mut head,
        ] {
            random_bias(conv, &device);
        }
        let chain = [
            (&stem, true),
            (&dw1, true),
            (&pw1, true),
            (&dw2, true),
            (&dw3, true),
            (&paired, true),
            (&full, false),
            (&head, false),
        ];
        let plain = PlainNet::from_convs(&chain).unwrap();
        // 70 × 83: the stem's rows are 42 wide (two 16-pixel blocks and a tail), the later
        // layers' 21 (a block and a tail); the others exercise the tails and tiny planes.
        for (n, h, w) in [(1, 70, 83), (2, 37, 29), (1, 8, 8), (1, 5, 3)] {
            let x: Tensor<4> =
                Tensor::random([n, 1, h, w], Distribution::Normal(0.0, 1.0), &device);
            let data = x.to_data().try_to_vec::<f32>().unwrap();
            let want = burn_chain(&chain, x);
            let [_, c, oh, ow] = want.dims();
            assert_eq!(plain.output_size(h, w), (oh, ow), "{h} × {w}");
            assert_eq!(plain.output_channels(), c);
            let want = want.into_data().try_to_vec::<f32>().unwrap();
            let got = plain.forward(&data, n, h, w);
            let largest = want.iter().fold(1.0f32, |m, v| m.max(v.abs()));
            let worst = largest_difference(&want, &got);
            assert!(worst <= 1e-5 * largest, "{h} × {w}: off by {worst}");
        }
        // The portable path too, where the CPU would have taken the fused one.
        let x: Tensor<4> = Tensor::random([1, 1, 21, 18], Distribution::Normal(0.0, 1.0), &device);
        let data = x.to_data().try_to_vec::<f32>().unwrap();
        let fused = plain.forward(&data, 1, 21, 18);
        let mut portable = Vec::new();
        let mut workspace = [vec![0.0; 21 * 18 * 8], vec![0.0; 21 * 18 * 8], Vec::new()];
        plain.images::<false, PORTABLE_LANES>(&data, 1, (21, 18), &mut workspace, &mut portable);
        let worst = largest_difference(&fused, &portable);
        assert!(worst < 1e-4, "paths differ by {worst}");
    }

    #[test]
    fn layers_it_cannot_run_are_named() {
        let device = Device::flex();
        let five = Conv2dConfig::new([2, 2], [5, 5]).init(&device);
        let err = PlainNet::from_convs(&[(&five, true)]).unwrap_err();
        assert_eq!(err.layer, 0);
        assert!(err.what.contains("kernel"), "{err}");
        let unpadded = Conv2dConfig::new([4, 4], [3, 3]).init(&device);
        let one = Conv2dConfig::new([4, 4], [1, 1]).init(&device);
        let err = PlainNet::from_convs(&[(&one, true), (&unpadded, true)]).unwrap_err();
        assert_eq!(err.layer, 1);
        assert!(err.what.contains("padding"), "{err}");
        let padded = Conv2dConfig::new([4, 4], [1, 1])
            .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
            .init(&device);
        let err = PlainNet::from_convs(&[(&padded, true)]).unwrap_err();
        assert!(err.what.contains("padding"), "{err}");
        let three = Conv2dConfig::new([3, 3], [1, 1]).init(&device);
        let err = PlainNet::from_convs(&[(&one, true), (&three, true)]).unwrap_err();
        assert!(err.what.contains("input channels"), "{err}");
    }
}
