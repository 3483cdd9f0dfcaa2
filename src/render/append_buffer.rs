//! A storage buffer that grows by appending: what it holds is written once, and when it
//! outgrows its buffer a larger one takes a copy on the GPU. The forest pass's shared
//! geometry is one: a hierarchical strategy publishes group impostors a few at a time, to
//! thousands of models and millions of vertices, and writing all of it again at each
//! publication stalled both worlds for tens of milliseconds.

use core::marker::PhantomData;

use bevy::render::render_resource::{
    BindingResource, Buffer, BufferDescriptor, BufferUsages, CommandEncoderDescriptor,
};
use bevy::render::renderer::{RenderDevice, RenderQueue};
use bytemuck::Pod;

/// How much larger a grown buffer is than what it must hold, as a share: each growth
/// copies what the buffer holds, so growing by a share keeps the copies' total a few
/// times the final size, and the unused capacity below that share.
const GROWTH: u64 = 4;

/// Values of `T` appended to one GPU storage buffer.
pub(super) struct AppendBuffer<T> {
    label: &'static str,
    buffer: Option<Buffer>,
    /// Values written.
    len: u64,
    values: PhantomData<T>,
}

impl<T: Pod> AppendBuffer<T> {
    pub(super) fn new(label: &'static str) -> Self {
        Self {
            label,
            buffer: None,
            len: 0,
            values: PhantomData,
        }
    }

    /// Forgets every value (the buffer is let go; the next append makes a new one).
    pub(super) fn clear(&mut self) {
        self.buffer = None;
        self.len = 0;
    }

    /// Writes `values` after those already written. The buffer exists afterwards even
    /// when nothing was ever written (storage buffers may not be empty). A buffer outgrown
    /// is replaced by one a quarter larger than needed (at most `limit` bytes, unless the
    /// values need more), which copies the old one's values on the GPU.
    pub(super) fn append(
        &mut self,
        values: &[T],
        limit: u64,
        device: &RenderDevice,
        queue: &RenderQueue,
    ) {
        let size = size_of::<T>() as u64;
        let written = self.len * size;
        let needed = (self.len + values.len() as u64).max(1) * size;
        let capacity = self.buffer.as_ref().map_or(0, |b| b.size());
        if needed > capacity {
            let grown = (needed + needed / GROWTH).min(limit.max(needed));
            // Whole values, a multiple of the copy alignment (4 bytes).
            let grown = (grown / size * size).max(needed).next_multiple_of(4);
            let buffer = device.create_buffer(&BufferDescriptor {
                label: Some(self.label),
                size: grown,
                usage: BufferUsages::STORAGE | BufferUsages::COPY_DST | BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            if let Some(old) = self.buffer.take()
                && written > 0
            {
                let mut encoder = device.create_command_encoder(&CommandEncoderDescriptor {
                    label: Some(self.label),
                });
                encoder.copy_buffer_to_buffer(&old, 0, &buffer, 0, written);
                queue.submit([encoder.finish()]);
            }
            self.buffer = Some(buffer);
        }
        if let Some(buffer) = &self.buffer
            && !values.is_empty()
        {
            queue.write_buffer(buffer, written, bytemuck::cast_slice(values));
        }
        self.len += values.len() as u64;
    }

    pub(super) fn buffer(&self) -> Option<&Buffer> {
        self.buffer.as_ref()
    }

    pub(super) fn binding(&self) -> Option<BindingResource<'_>> {
        self.buffer
            .as_ref()
            .map(|buffer| buffer.as_entire_binding())
    }
}
