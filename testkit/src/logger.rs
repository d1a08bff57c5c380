//! The one test logger: an FMI 2.0 `fmi2CallbackLogger` that records every
//! message into a [`LogBook`] passed as the component environment.
//!
//! FMI's logger is a C variadic function, which stable Rust cannot define.
//! The layer always calls it as `logger(env, name, status, category, "%s",
//! text)`, so the test logger is a non-variadic `extern "C" fn` taking that
//! one extra `const char*` argument, transmuted to the variadic pointer type.
//! That is sound on the SysV x86-64 and AAPCS64 (Linux) calling conventions,
//! where a variadic argument of pointer type is passed exactly like the next
//! named argument (the caller only also sets `%al`, which a non-variadic
//! callee ignores); it would not be on Apple arm64, where variadic arguments
//! go on the stack.
//!
//! Entry points: [`callbacks`] (the logger writing into a book),
//! [`callbacks_with`] (any [`FixedLogger`] and environment).

use std::ffi::{c_char, c_void, CStr};
use std::fmt;
use std::sync::Mutex;

use hill_muscle::fmi2::types::*;

/// One logged message.
#[derive(Clone)]
pub struct Entry {
    /// The instance name, as passed (bytes: it need not be UTF-8).
    pub instance: Vec<u8>,
    pub status: fmi2Status,
    pub category: String,
    /// The format string (the layer always passes `"%s"`).
    pub format: String,
    /// The text, the format's one argument.
    pub message: String,
}

impl fmt::Debug for Entry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "[{} {:?} {} {:?}] {:?}",
            String::from_utf8_lossy(&self.instance),
            self.status,
            self.category,
            self.format,
            self.message
        )
    }
}

/// The messages logged so far (behind a mutex: FMI 2.0 allows an instance
/// to be used from another thread between calls).
#[derive(Default)]
pub struct LogBook {
    entries: Mutex<Vec<Entry>>,
}

impl LogBook {
    /// The messages, emptying the book.
    pub fn take(&self) -> Vec<Entry> {
        std::mem::take(&mut *self.entries.lock().unwrap())
    }

    /// A copy of the messages.
    pub fn entries(&self) -> Vec<Entry> {
        self.entries.lock().unwrap().clone()
    }

    pub fn clear(&self) {
        self.entries.lock().unwrap().clear();
    }
}

/// The bytes of a C string; `<NULL>` for a null pointer.
pub(crate) fn c_bytes(p: *const c_char) -> Vec<u8> {
    if p.is_null() {
        b"<NULL>".to_vec()
    } else {
        unsafe { CStr::from_ptr(p) }.to_bytes().to_vec()
    }
}

/// [`c_bytes`] as text (invalid UTF-8 replaced).
pub(crate) fn c_text(p: *const c_char) -> String {
    String::from_utf8_lossy(&c_bytes(p)).into_owned()
}

/// See the module docs: the fixed arguments plus the one `%s` argument.
unsafe extern "C" fn test_logger(
    env: fmi2ComponentEnvironment,
    instance_name: fmi2String,
    status: fmi2Status,
    category: fmi2String,
    message: fmi2String,
    arg: *const c_char,
) {
    if env.is_null() {
        return;
    }
    let book = unsafe { &*(env as *const LogBook) };
    let e = Entry {
        instance: c_bytes(instance_name),
        status,
        category: c_text(category),
        format: c_text(message),
        message: c_text(arg),
    };
    if let Ok(mut g) = book.entries.lock() {
        g.push(e);
    }
}

/// A logger with the fixed arguments plus the one `%s` argument.
pub type FixedLogger = unsafe extern "C" fn(
    fmi2ComponentEnvironment,
    fmi2String,
    fmi2Status,
    fmi2String,
    fmi2String,
    *const c_char,
);

/// The callbacks logging into `book`, which must outlive the instance.
pub fn callbacks(book: &LogBook) -> fmi2CallbackFunctions {
    callbacks_with(test_logger, book as *const LogBook as *mut c_void)
}

/// The callbacks with `fixed` as the logger and `env` as the
/// componentEnvironment.
pub fn callbacks_with(fixed: FixedLogger, env: fmi2ComponentEnvironment) -> fmi2CallbackFunctions {
    fmi2CallbackFunctions {
        // SAFETY: see the module docs.
        logger: Some(unsafe {
            std::mem::transmute::<
                FixedLogger,
                unsafe extern "C" fn(
                    fmi2ComponentEnvironment,
                    fmi2String,
                    fmi2Status,
                    fmi2String,
                    fmi2String,
                    ...
                ),
            >(fixed)
        }),
        allocateMemory: None,
        freeMemory: None,
        stepFinished: None,
        componentEnvironment: env,
    }
}
