//! The frame as the base layer sees it: something that renders on its own threads, reports
//! when it is done, answers property queries and hands out mapped channels. The renderer
//! layer implements it; objects hold it without knowing how frames render.

use std::any::Any;
use std::ffi::c_void;
use std::sync::Arc;

use crate::device::datatype::ANARIDataType;
use crate::device::property::PropertyValue;

pub trait Frame: Send + Sync {
    /// Whether no render is in flight (or the caller is the frame's own completion callback).
    fn is_ready(&self) -> bool;

    /// Blocks until no render is in flight.
    fn wait(&self);

    /// Asks the render in flight to stop after the tiles being rendered now.
    fn discard(&self);

    /// A frame property ("duration", "progress", …); `wait` waits for the render first.
    fn property(&self, name: &str, wait: bool) -> Option<PropertyValue>;

    /// Waits for the render and returns the channel's pixels, width, height and type (kept
    /// alive until unmap).
    fn map(&self, channel: &str) -> Option<(*const c_void, u32, u32, ANARIDataType)>;

    /// Ends the oldest mapping of the channel; false when it is not mapped.
    fn unmap(&self, channel: &str) -> bool;

    /// The frame as its concrete type, for the layer that made it.
    fn into_any(self: Arc<Self>) -> Arc<dyn Any + Send + Sync>;
}
