//! Images: windows of a full frame, PNG and EXR output, merging windows (being written).
