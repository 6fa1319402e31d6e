// Starts a page's WebAssembly build, as wasm-bindgen writes it (`path`, relative to the page).
// winit leaves its event loop by throwing; that is not an error.
export async function start(path) {
  const { default: init } = await import(path);
  init().catch((error) => {
    if (!String(error).includes("Using exceptions for control flow")) throw error;
  });
}
