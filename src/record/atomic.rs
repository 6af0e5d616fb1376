//! How a record's files, and every other file cdlab writes, are replaced without a window
//! in which none is complete. The one helper that does it is [`crate::fsio`], low in the
//! module map so that `sample` and `figures` use it too; its items are re-exported here
//! under the names the record's callers use.

pub use crate::fsio::{
    TMP_SUFFIX, check_replaceable, create_tmp, fault, process_tmp_path, remove_file, remove_stale_tmps,
    rename, sync_dir, tmp_path, write_file,
};
