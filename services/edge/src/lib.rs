//! The HTTP edge shared by the services: the JSON error type with stable codes, and the middleware stack.
